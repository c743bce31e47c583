//! Explicit MLS-MPM with quadratic B-splines and APIC transfers on a distributed grid
//! (PhysGaussian §3.3).
//
// Decomposition: the grid is a PETSc DMDA over nodes with a box stencil of width 1 and
// per-axis slabs balanced by the particle count. A particle belongs to the rank that owns its
// nearest node, so its 3x3x3 B-spline footprint lies in that rank's ghosted box. P2G adds into
// the ghosted box and one DMDA scatter-add sums the overlaps; after it every rank holds complete
// sums on its whole ghosted box, so the grid update runs there redundantly and G2P needs no
// second exchange. Particles then migrate (all-to-all) to the owner of their new nearest node.
//
// Bit-identical results at any rank count: each P2G contribution is rounded to an integer
// multiple of a power-of-two quantum chosen from the global maximum contribution (2^-40 of it),
// so node sums are exact integer sums in double precision (below 2^53), independent of order
// and of how particles are split across ranks. Everything else is per particle or per node.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/Config.hpp"
#include "core/Error.hpp"
#include "core/Timers.hpp"
#include "mpm/DeviceSubstep.hpp"
#include "mpm/Kernels.hpp"
#include "mpm/Material.hpp"
#include "mpm/MaterialSet.hpp"
#include "mpm/Particles.hpp"
#include "parallel/Comm.hpp"
#include "parallel/Grid.hpp"
#include "parallel/Halo.hpp"

namespace gen4d::mpm {

//! The background grid: node (i, j, k) sits at lo + (i, j, k) dx, for i in [0, cells].
struct GridSpec {
  Vec3d lo{0, 0, 0};
  double dx = 0;
  std::array<long, 3> cells{0, 0, 0};
  std::array<long, 3> nodes() const { return {cells[0] + 1, cells[1] + 1, cells[2] + 1}; }
};

struct SolverOptions {
  Vec3d gravity{0, 0, -9.81};
  double max_dt = 1e-3;              //!< s
  bool adaptive = true;              //!< false: every substep is max_dt
  double cfl = 0.3;                  //!< dt <= cfl dx / max speed
  double wave_cfl = 0.5;             //!< dt <= wave_cfl dx / elastic wave speed
  bool remove_outside = false;       //!< particles leaving the grid: removed (else clamped)
  int boundary_layers = 3;           //!< node layers of the bounding-box walls
  double max_cells_per_substep = 1;  //!< instability guard
  //! Mass-proportional damping alpha (1/s): the grid velocity after gravity is divided by
  //! 1 + alpha dt (implicit, stable at any alpha); 0 leaves the update untouched.
  double damping = 0;
  //! P2G's affine matrix C -> (1 - r) C + r skew(C) (PhysGaussian's RPIC damping: r = 1 keeps
  //! only C's rotation part); 0: APIC; -1: PIC (C = 0). The particles keep their C.
  double rpic_damping = 0;
  //! Grid velocities (after gravity) are multiplied by this every substep; 1: off.
  double grid_velocity_scale = 1;
  //! Called every substep after the material's update with this rank's particles and their
  //! Kirchhoff stresses (9 per particle, row-major), which it may change before P2G; empty: no
  //! call. Diagnose's MPM model adds its effects' stresses here (a region's stiffness factor,
  //! a Prony term, stiffness-proportional damping). It must act per particle (by id) for the
  //! results to stay independent of the rank count.
  std::function<void(const Particles&, double* tau, double dt)> stress_hook;
  //! In a CUDA build, run P2G, the grid update and G2P on this rank's GPU when it has one
  //! (core/Device.hpp); false: always the host.
  bool allow_device = true;
};

//! The deck's solver options ([simulation] gravity and dt as the largest substep, [mpm]):
//! the one translation of a Config every MPM caller starts from.
SolverOptions solver_options(const Config& cfg);

//! A `surface_collider` boundary condition (the plane through `point` with `normal` towards the
//! allowed side), active for the whole run.
inline BoundaryConfig surface_collider(const std::string& surface, const Vec3d& point,
                                       const Vec3d& normal, double friction = 0) {
  BoundaryConfig b;
  b.type = "surface_collider";
  b.surface = surface;
  b.point = point;
  b.normal = normal;
  b.friction = friction;
  return b;
}

//! The box of a `cuboid` condition at time t: its lo/hi, shifted by
//! velocity (clamp(t, start, end) - start) when it is "moving".
inline BoxRegion cuboid_region(const BoundaryConfig& b, double t) {
  if (b.motion != "moving") return b.region;
  const double tau = b.curve.integral(b.start, std::clamp(t, b.start, b.end));
  BoxRegion r = b.region;
  for (int d = 0; d < 3; ++d) {
    r.lo[d] += b.velocity[d] * tau;
    r.hi[d] += b.velocity[d] * tau;
  }
  return r;
}

//! A particle that went non-finite or moved too far in one substep: the run is unstable.
class InstabilityError : public RuntimeError {
 public:
  explicit InstabilityError(const std::string& what) : RuntimeError(what) {}
};

class Solver {
 public:
  //! `materials`: one material, or a MaterialSet whose slots the particles' `material` name.
  Solver(MPI_Comm comm, const GridSpec& grid, MaterialSet materials, const SolverOptions& options,
         std::vector<BoundaryConfig> boundaries);
  ~Solver();

  //! Takes this rank's particles (any subset), builds the balanced grid from the global
  //! particle distribution and migrates every particle to its owner. Collective.
  void distribute(Particles local);
  //! Largest admissible substep not exceeding `limit` (collective).
  double stable_dt(double limit) const;
  //! Advances particles from time t by dt. Collective. Throws InstabilityError (every rank).
  void substep(double t, double dt);

  Particles& particles() { return p_; }
  const Particles& particles() const { return p_; }
  const GridSpec& spec() const { return spec_; }
  const SolverOptions& options() const { return opt_; }
  const parallel::NodeGrid& grid() const { return *grid_; }
  const MaterialSet& materials() const { return materials_; }
  const Material& material() const { return materials_[0]; }  //!< slot 0
  //! Whether P2G, the grid update and G2P run on a GPU (known after distribute()).
  bool on_device() const;
  PhaseTimers& timers() { return timers_; }
  const PhaseTimers& timers() const { return timers_; }

  // Collective diagnostics (exact sums: identical at any rank count).
  long long count() const;
  double total_mass() const;
  std::array<double, 3> total_momentum() const;
  double kinetic_energy() const;
  long long removed() const { return removed_total_; }  //!< all ranks, since the start
  long long clamped() const { return clamped_total_; }
  long long migrated() const { return migrated_total_; }
  //! Restores counters after a restart.
  void set_counters(long long removed, long long clamped) {
    removed_total_ = removed;
    clamped_total_ = clamped;
  }
  //! Rank owning the nearest node of position x (after clamping into the grid).
  int owner_of(const double* x) const;

 private:
  void build_grid();
  void update_stress(double dt);
  void p2g(double dt);
  void grid_update(double t, double dt);
  void g2p(double t, double dt);
  void particle_conditions(double t, double dt);
  void check_and_confine(double t, double dt);
  kernels::GuardArgs guard_args(double dt);
  void migrate();
  bool frozen(std::size_t i, double t) const;

  MPI_Comm comm_;
  int rank_ = 0, size_ = 1;
  GridSpec spec_;
  MaterialSet materials_;
  SolverOptions opt_;
  std::vector<BoundaryConfig> bcs_;
  Particles p_;
  std::unique_ptr<parallel::NodeGrid> grid_;
  std::unique_ptr<parallel::Halo> halo4_;
  std::vector<double> pm_;   // ghosted box, 4 per node: mass, momentum (in quanta)
  std::vector<double> vel_;  // ghosted box, 3 per node
  // Host P2G's slab colouring: each particle's slab, the particles by slab, slab offsets.
  std::vector<std::int32_t> slab_of_;
  std::vector<long> order_, slab_start_;
  std::vector<int> dest_;                      // migration: owner per particle
  std::array<std::vector<int>, 3> rank_part_;  // owner_of's term per axis and node
  std::vector<std::uint8_t> status_;           // guard, per particle
  bool guarded_ = false;  // status_ already holds this substep's guard (fused into G2P)
  std::vector<kernels::GridCondition> grid_conditions_;  // of the substep at hand
#if defined(GEN4D_CUDA)
  device::WorkspacePtr device_;  // set when the kernels run on this rank's GPU
#endif
  std::vector<double> tau_;  // per particle Kirchhoff stress (9)
  double quantum_mass_ = 1, quantum_mom_ = 1;
  // release_particles_sequentially: projection range of the initial particles on its normal
  std::vector<std::array<double, 2>> release_range_;
  long long removed_total_ = 0, clamped_total_ = 0, migrated_total_ = 0;
  PhaseTimers timers_;
};

}  // namespace gen4d::mpm
