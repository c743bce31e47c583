//! A whole MPM run from a deck (solver.method = "mpm"): particles seeded from the geometry,
//! the substep loop with progress lines, particle frames (HDF5 + XDMF, optional PLY and VDB
//! per frame), checkpoints (periodic, final, on SIGTERM/SIGUSR1, and of the last good frame
//! when the instability guard stops the run) and restart at any rank count.
//!
//! Splats: `[[geometry]] type = "splats"` parts become one particle per Gaussian (the other
//! parts are lattice-seeded as before). When the deck has splats or a [render] table, every
//! particle carries splat attributes (mpm/SplatParticles.hpp; lattice particles get isotropic
//! splats of their part's colour), which follow the flow every substep; [render] draws them to
//! OUT/png/frame_NNNNNN.png per output frame (optionally OUT/render.mp4), and output.particles
//! = "ply" also writes the deformed splats as 3DGS PLYs, OUT/splats/splats_NNNNNN.ply.
#pragma once

#include <memory>
#include <string>

#include "core/Config.hpp"
#include "geometry/Shape.hpp"
#include "gaussians/RunRender.hpp"
#include "gaussians/Kinematics.hpp"
#include "mpm/ParticleIO.hpp"
#include "mpm/Solver.hpp"
#include "mpm/SplatParticles.hpp"
#include "parallel/Comm.hpp"

namespace gen4d::mpm {

struct MpmRunResult {
  int exit_code = 0;  //!< 0 finished, 1 stopped by a signal
  long substeps = 0;  //!< substeps taken by this process
  double wall_seconds = 0;
  std::string last_checkpoint;
};

//! Grid of a deck: [mpm] lo/hi, else the object's bounds padded by max(domain.padding,
//! mpm.boundary_layers + 2) cells.
GridSpec layout_grid(const Config& cfg, const geometry::Aabb& object);
//! The deck's material for the MPM registry (InputError naming the deck key when invalid).
std::shared_ptr<const Material> make_deck_material(const Config& cfg);
//! Every material of the deck: slot 0 the first, slot k its k-th later [[material]] entry.
MaterialSet make_deck_materials(const Config& cfg);
//! Sets the material slot of freshly seeded particles (material_slot of the deck): lattice
//! particles (ids below `lattice_count`) belong to the first of the deck's non-splat parts that
//! holds them, the others to `splat_part[id - lattice_count]` (a Config::geometry index). Mass
//! (density times rest volume) and state are made again for slots other than 0.
void assign_material_slots(const Config& cfg, const MaterialSet& materials,
                           std::int64_t lattice_count, const std::vector<int>& splat_part,
                           Particles& p);

//! The MPM grid conditions of a deck: its [[boundary]] entries, then its [[collider]]
//! obstacles: a plane as a surface_collider that lets material leave ("separate") with the
//! collider's Coulomb friction, a box as a still cuboid (the grid nodes inside stop).
std::vector<BoundaryConfig> boundary_conditions(const Config& cfg);
//! Particles whose B-spline footprint reaches the wall nodes (`layers` node layers at each
//! grid face), over all ranks.
struct WallCount {
  std::array<long long, 6> per_wall{};  //!< x-, x+, y-, y+, z-, z+ (an edge counts twice)
  long long particles = 0;              //!< particles at one wall or more
};
//! Counts this rank's particles `p` at the walls, summed over `comm`. Collective.
WallCount particles_at_walls(MPI_Comm comm, const GridSpec& spec, int layers, const Particles& p);

class MpmSimulation {
 public:
  //! Builds material, grid and particles (seeded unless `seed` is false: restart). Collective.
  MpmSimulation(MPI_Comm comm, const Config& cfg, bool seed = true);
  ~MpmSimulation();

  //! Replaces the particles, clock and counters with a checkpoint's (any rank count).
  void load_checkpoint(const std::string& path);
  //! Runs to simulation.end_time writing into out_dir; `append` continues the frame file.
  MpmRunResult run(const std::string& out_dir, bool append);

  Solver& solver() { return *solver_; }
  long substep_index() const { return step_; }
  double time() const { return time_; }
  std::int64_t total_particles() const { return total_; }
  //! Whether the particles carry splat attributes, and their layout.
  bool carries_splats() const { return carries_splats_; }
  const SplatLayout& splat_layout() const { return layout_; }

 private:
  struct Snapshot {
    Particles particles;
    long step = 0;
    double time = 0;
    long frame_index = 0;
    double next_frame_time = 0;
  };
  double frame_interval() const;
  std::string write_checkpoint(const std::string& out_dir, const Snapshot* from = nullptr);
  void write_frame(ParticleFrameWriter& writer, const std::string& out_dir);
  //! The [render] image of frame `index` (collective; rank 0 writes it).
  void render_frame(int index);
  void take_snapshot();
  //! Counts the particles at the grid walls (particles_at_walls; collective) and warns the
  //! first time there are any.
  void check_walls();
  void report_timers(double wall, long substeps) const;

  MPI_Comm comm_;
  Config cfg_;
  int rank_ = 0, size_ = 1;
  GridSpec spec_;
  std::unique_ptr<Solver> solver_;
  std::int64_t total_ = 0;
  long step_ = 0;
  double time_ = 0;
  long frame_index_ = 0;
  double next_frame_time_ = 0;
  Snapshot snapshot_;
  double io_seconds_ = 0;
  long long at_walls_ = 0;  //!< particles at the grid walls at the last frame
  bool walls_warned_ = false;
  bool carries_splats_ = false;
  SplatLayout layout_;
  CovarianceUpdate covariance_update_ = CovarianceUpdate::DeformationGradient;
  gaussians::KinematicsOptions kinematics_;
  std::unique_ptr<gaussians::RunRenderer> renderer_;  //!< null without a [render] table
};

}  // namespace gen4d::mpm
