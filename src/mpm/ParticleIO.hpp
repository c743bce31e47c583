//! Output and restart files of the MPM particles: HDF5 checkpoints and frames (with a ParaView
//! XDMF index), and point clouds for artists' tools (PLY, OpenVDB) and quick PNG looks.
//
// Particle arrays are stored by global id: row `id` of every dataset belongs to particle `id`,
// for ids 0..N-1 (N = particles at seeding). Ids of removed particles are holes: their rows
// hold zeros and `alive` = 0. To write, each rank sends its particles to the rank owning their
// id block (rank r of P owns ids [r N / P, (r + 1) N / P)), which writes that block as one
// contiguous hyperslab, so every rank count and distribution writes the same file contents.
//
// Every function here is collective on `comm`; a rank holding no particles still calls it.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "io/Checkpoint.hpp"
#include "io/FramesFile.hpp"
#include "io/Hdf5.hpp"
#include "mpm/Particles.hpp"
#include "parallel/Comm.hpp"

namespace gen4d::mpm {

inline constexpr const char* kParticleCheckpointFormat = "gen4d-mpm-checkpoint";
//! 2 added the per-particle material slot; version 1 files are read with every slot 0.
inline constexpr long kParticleCheckpointFormatVersion = 2;
inline constexpr const char* kParticleFramesFormat = "gen4d-mpm-frames";
inline constexpr long kParticleFramesFormatVersion = 1;

//! Rows [begin, begin + count) of the id block that rank `rank` of `size` writes and reads.
struct IdBlock {
  std::int64_t begin = 0;
  std::int64_t count = 0;
};
IdBlock id_block(std::int64_t total, int rank, int size);
//! The rank whose id_block holds `id` (0 <= id < total).
int id_block_owner(std::int64_t id, std::int64_t total, int size);

// ---- checkpoints ---------------------------------------------------------------------------

//! What write_particle_checkpoint stores: the run's clock, deck, the particle count N, the
//! names of the used state slots, solver scalars, and this rank's particles.
struct ParticleCheckpointState : io::RunClock {
  std::int64_t total_particles = 0;      //!< N: ids are 0..N-1
  std::vector<std::string> state_names;  //!< at most kStateSize
  //! Names of the particles' extra values (as many as their extra_width), stored as the
  //! attribute extra_names with the dataset extra [N][W] (absent when W = 0).
  std::vector<std::string> extra_names;
  const Particles* particles = nullptr;  //!< this rank's particles (any distribution)
};

//! Everything in a particle checkpoint except the particle arrays.
struct ParticleCheckpointMeta : io::RunClock {
  std::int64_t total_particles = 0;
  std::vector<std::string> state_names;
  std::vector<std::string> extra_names;  //!< empty in a checkpoint without extra values
};

//! Writes dir/checkpoint_<step, 8 digits>.h5 (io::checkpoint_path) collectively: the file is
//! written as dir/.checkpoint_<step>.h5.tmp, then rank 0 renames it and deletes all but the
//! newest `keep` checkpoints of `dir` (keep <= 0 keeps all). Returns the path on every rank
//! once it exists. Ids outside 0..N-1 or held twice, a failure to create `dir` or to write are
//! RuntimeErrors on every rank, and nothing is left under the final name.
//! io::latest_checkpoint(dir) finds the newest one for a restart.
std::string write_particle_checkpoint(MPI_Comm comm, const std::string& dir,
                                      const ParticleCheckpointState& state, int keep);

//! First phase of a restart: the metadata, read and checked on rank 0 and shared. InputError
//! on every rank naming the file and the problem (missing, not HDF5, damaged, another format
//! or version, missing or misshaped dataset or attribute).
ParticleCheckpointMeta read_particle_checkpoint_meta(MPI_Comm comm, const std::string& path);

//! Both phases: the metadata and, into `particles` (replaced, sorted by id, extra_width the
//! number of extra_names), the alive particles of this rank's id block. The caller then migrates
//! them to their spatial owners. Any defect, also a non-finite value in an alive particle, is an
//! InputError on every rank naming the file, and `particles` is left unchanged.
ParticleCheckpointMeta read_particle_checkpoint(MPI_Comm comm, const std::string& path,
                                                Particles& particles);

// ---- frames ----------------------------------------------------------------------------------

//! A scalar output field: one value per local particle, aligned with the Particles arrays.
//! Names use letters, digits, '_', '-' and '.', and must not be position, velocity or alive.
struct ParticleScalar {
  std::string name;
  const double* values = nullptr;
};

struct ParticleFrameInfo {
  int index = 0;  //!< group /frames/<index, 6 digits>
  int step = 0;
  double time = 0;
  std::vector<std::string> fields;  //!< scalar fields stored with the frame, in order
};

//! One HDF5 file of every frame of a run, /frames/NNNNNN holding float64 position and
//! velocity [N][3], uint8 alive [N] and one float64 [N] dataset per scalar field (rows of
//! removed ids are zeros with alive = 0), attributes time and step. After each frame the file
//! is flushed and rank 0 replaces the XDMF index beside it (particles.h5 -> particles.xdmf):
//! a temporal collection of Polyvertex grids over the N points, geometry from position, every
//! dataset as a node attribute, so ParaView opens an unfinished run. Dead particles sit at the
//! origin: threshold on `alive` to hide them.
class ParticleFrameWriter {
 public:
  //! Creates (truncates) `h5_path` for `total_particles` ids, with free-form string
  //! attributes on the root group (deck text, version). RuntimeError when it cannot.
  ParticleFrameWriter(MPI_Comm comm, const std::string& h5_path, std::int64_t total_particles,
                      const std::map<std::string, std::string>& attributes = {});
  //! Reopens a particle frames file for a restarted run, keeping frames with step <=
  //! `keep_up_to_step` and deleting later ones. InputError when it is not one.
  static ParticleFrameWriter open_append(MPI_Comm comm, const std::string& h5_path,
                                         int keep_up_to_step);

  ParticleFrameWriter(ParticleFrameWriter&&) = default;
  ParticleFrameWriter& operator=(ParticleFrameWriter&&) = default;
  ~ParticleFrameWriter() = default;

  //! Appends a frame of this rank's particles and `fields` (the same names, in the same
  //! order, on every rank). RuntimeError on every rank for a bad field or id, or a write
  //! failure; the file then holds only the complete frames.
  void write_frame(double time, int step, const Particles& particles,
                   const std::vector<ParticleScalar>& fields = {});
  //! Closes the file, reporting a failure to finish writing it (RuntimeError).
  void close();

  const std::vector<ParticleFrameInfo>& frames() const { return frames_; }
  std::int64_t total_particles() const { return total_; }
  const std::string& path() const { return file_.path(); }
  const std::string& xdmf_path() const { return file_.xdmf_path(); }

 private:
  ParticleFrameWriter(io::FramesFile file, std::int64_t total);
  void commit();

  io::FramesFile file_;
  std::int64_t total_ = 0;
  std::vector<ParticleFrameInfo> frames_;
};

//! The XDMF index of `frames` of the particle frames file `h5_name` (relative to the index).
std::string particle_xdmf_text(const std::string& h5_name, std::int64_t total_particles,
                               const std::vector<ParticleFrameInfo>& frames);

// ---- point clouds and images ---------------------------------------------------------------

//! Binary little-endian PLY point cloud of the particles, in id order: element vertex with
//! float x, y, z, vx, vy, vz. Gathers every particle to rank 0 (memory and one MPI message of
//! 7 doubles per particle there), which writes a temporary beside `path` and renames it.
//! RuntimeError on every rank when it cannot be written.
void write_particle_ply(MPI_Comm comm, const std::string& path, const Particles& particles);

//! OpenVDB file with the particles splatted (trilinear weights) onto voxels of edge
//! `voxel_size`: FloatGrid "density" (fog volume, kg/m^3 = mass / voxel volume, so the sum of
//! density times voxel volume is the total mass) and Vec3SGrid "velocity" (mass-weighted
//! mean, m/s, contravariant-relative). Transform: linear, voxel size `voxel_size`; voxel
//! (i, j, k) is centred at world (i, j, k) * voxel_size. Gathers every particle to rank 0
//! (8 doubles per particle), which writes a temporary and renames it. InputError for a
//! non-positive voxel size, RuntimeError on every rank when it cannot be written.
void write_particle_vdb(MPI_Comm comm, const std::string& path, const Particles& particles,
                        double voxel_size);

//! An orthographic look along a coordinate axis at the world box [lo, hi].
struct ParticleView {
  //! 0: from +x (right = +y, up = +z); 1: from -y (right = +x, up = +z); 2: from +z (right =
  //! +x, up = +y). Nearer particles are drawn brighter.
  int axis = 1;
  int width = 640, height = 480;
  std::array<double, 3> lo{0, 0, 0}, hi{1, 1, 1};  //!< fitted into the image, aspect kept
  int point_radius = 1;                            //!< pixels around each particle's pixel
};

//! Depth-shaded point splat PNG of the particles inside the view box. Each rank draws its own
//! particles into a depth buffer, reduced to rank 0, which writes the PNG through a
//! temporary. InputError for a bad view, RuntimeError on every rank when it cannot be written.
void write_particle_png(MPI_Comm comm, const std::string& path, const Particles& particles,
                        const ParticleView& view);

// ---- reading frames back (serial, for previews) --------------------------------------------

//! The frames of a particle frames file, read on this process alone. InputError naming the
//! file for anything that is not a gen4d particle frames file.
std::vector<ParticleFrameInfo> read_particle_frame_list(const std::string& h5_path);
//! Positions and velocities of the alive particles of frame `index` (ids kept), serial.
Particles read_particle_frame(const std::string& h5_path, int index);
//! Renders frames (positions in `frames`) of a particle frames file to OUT/particles_NNNNNN.png
//! looking along -y, one view box framing every chosen frame; returns the files. Serial.
std::vector<std::string> render_particle_frames(const std::string& h5_path,
                                                const std::vector<int>& frames,
                                                const std::string& out_dir, int width, int height);

}  // namespace gen4d::mpm
