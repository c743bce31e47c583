//! A whole ElastoGen run: domain set-up from the deck, the time loop with progress lines,
//! HDF5 frames, surfaces and rendered splats, checkpoints (periodic, final, on SIGTERM/SIGUSR1)
//! and restart.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "core/Config.hpp"
#include "core/Timers.hpp"
#include "elastogen/Elastodynamics.hpp"
#include "elastogen/SplatEmbedding.hpp"
#include "elastogen/SurfaceEmbedding.hpp"
#include "gaussians/RunRender.hpp"
#include "gaussians/Kinematics.hpp"
#include "geometry/Shape.hpp"
#include "io/FrameWriter.hpp"
#include "io/SurfaceIO.hpp"
#include "parallel/Grid.hpp"
#include "parallel/Comm.hpp"

namespace gen4d::elastogen {

//! The cell edges (hx, hy, hz) of a deck: Config::spacing; where code set Config::voxel_size
//! alone (spacing unset or out of date), cubes of that edge, or the deck's edges scaled so
//! that the largest is voxel_size.
Vec3d cell_edges(const Config& cfg);

//! Global grid of a deck: origin and node counts enclosing the object plus padding.
struct DomainLayout {
  Vec3d origin{0, 0, 0};
  std::array<long, 3> nodes{0, 0, 0};
};
DomainLayout layout_domain(const Config& cfg, const geometry::Shape& shape);
//! The same for an object with world bounds `bounds`.
DomainLayout layout_domain(const Config& cfg, const geometry::Aabb& bounds);

//! The object of a deck: the solid its voxels are made from and, where the deck has splat parts
//! or a [render] table, the splats that show it.
//! - A "splats" part is loaded by gaussians::load_geometry_splats and occupies the voxels of
//!   gaussians::SplatOccupancy on the run's grid (cells of edge voxel_size anchored at the
//!   layout's origin, which the splat means' bounds and the other parts' bounds decide).
//! - Every other part is geometry::make_shape's, and is shown by gaussians::splats_from_shape at
//!   render.splat_spacing (voxel_size / 2 when 0) in the part's colour.
//! Parts keep the deck's order in the union and in the splat set (splat i of a part follows
//! every splat of the parts before it). InputError names the [[geometry]] table at fault.
struct DeckObject {
  DomainLayout layout;
  std::unique_ptr<geometry::Shape> shape;
  bool has_splat_parts = false;
  bool has_splats = false;     //!< `splats` was built (splat parts or a [render] table)
  gaussians::SplatSet splats;  //!< every rank holds all of them
  //! Each [[geometry]] part's own shape (owned by `shape`), when the deck has [[material]]
  //! entries bound to parts; empty otherwise.
  std::vector<const geometry::Shape*> parts;
  std::vector<std::unique_ptr<geometry::Shape>> own_parts;  //!< where `shape` is not their union
};
DeckObject build_deck_object(const Config& cfg);

struct RunResult {
  int exit_code = 0;  //!< 0 finished, 1 stopped by a signal or failure
  long steps = 0;     //!< steps taken by this process
  double wall_seconds = 0;
  std::string last_checkpoint;
};

class Simulation {
 public:
  //! Builds grid, voxels and solver; throws InputError for bad geometry. Writes nothing.
  Simulation(MPI_Comm comm, const Config& cfg);
  ~Simulation();

  //! Loads step, time and state from a checkpoint (any rank count).
  void load_checkpoint(const std::string& path);
  //! The state of frame 0: the rest state, or with pre-loads the static equilibrium under them
  //! (Elastodynamics::settle_preloads). run() calls it for a fresh run; once per simulation.
  void prepare_start();
  //! Runs to end_time writing frames/checkpoints to out_dir. `append` continues the
  //! frame file of an earlier run (restart).
  RunResult run(const std::string& out_dir, bool append);

  Elastodynamics& dynamics() { return *dyn_; }
  VoxelSystem& system() { return *sys_; }
  const parallel::NodeGrid& grid() const { return *grid_; }
  long step_index() const { return step_; }
  double time() const { return time_; }
  PhaseTimers& timers() { return timers_; }
  //! The cell edges the run uses.
  const Vec3d& spacing() const { return spacing_; }
  //! The surface written per frame (output.surface != "none"), else null.
  const SurfaceEmbedding* surface() const { return surface_.get(); }
  //! The splats carried by the voxels (splat parts or a [render] table), else null.
  const SplatEmbedding* splats() const { return splats_.get(); }
  //! Owned-node positions / velocities packed x-fastest (3 per node), for output and tests.
  std::vector<double> owned_positions() const;
  std::vector<double> owned_velocities() const;

 private:
  std::vector<double> pack_owned(const std::vector<double>& field) const;
  void unpack_owned(const std::vector<double>& packed, std::vector<double>& field) const;
  std::vector<std::uint8_t> owned_occupancy() const;
  std::string write_checkpoint(const std::string& out_dir);
  //! Creates out_dir (rank 0, failure shared) and the frame file, or reopens it to append.
  std::unique_ptr<io::FrameWriter> open_frames(const std::string& out_dir, bool append);
  void write_frame(io::FrameWriter& writer);
  //! Creates out_dir/surface and removes sequence files later than the frames kept (all of
  //! them for a fresh run) so the sequence matches frames.h5. Collective.
  void open_surface(const std::string& out_dir, const io::FrameWriter& writer);
  //! Writes the surface of frame `index` (rank 0 writes; every rank evaluates). Collective.
  void write_surface(long index);
  //! Renders the splats of frame `index` to png/frame_NNNNNN.png (rank 0 writes). Collective.
  void render_frame(long index);
  void report_timers(double wall, long steps) const;

  MPI_Comm comm_;
  Config cfg_;
  Vec3d spacing_{0, 0, 0};
  bool started_ = false;  // prepare_start() ran
  int rank_ = 0, size_ = 1;
  DomainLayout layout_;
  std::unique_ptr<parallel::NodeGrid> grid_;
  std::unique_ptr<VoxelSystem> sys_;
  PhaseTimers timers_;
  std::unique_ptr<Elastodynamics> dyn_;
  long step_ = 0;
  double time_ = 0;
  long frame_index_ = 0;
  double next_frame_time_ = 0;
  std::unique_ptr<SurfaceEmbedding> surface_;
  io::SurfaceFormat surface_format_ = io::SurfaceFormat::Ply;
  io::SurfaceMesh surface_mesh_;  // rank 0: triangles fixed, positions per frame
  std::string surface_dir_;
  long surface_files_ = 0;
  double surface_gather_seconds_ = 0, surface_write_seconds_ = 0, surface_bytes_ = 0;
  std::unique_ptr<SplatEmbedding> splats_;
  gaussians::KinematicsOptions kinematics_;
  std::unique_ptr<gaussians::RunRenderer> renderer_;  //!< null without a [render] table
};

}  // namespace gen4d::elastogen
