//! ElastoGen time stepping: implicit Euler as a nested recurrent loop (RNN-1 outer loop of
//! local targets, RNN-2 global relaxation) followed by the true-residual accuracy check.
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "core/Config.hpp"
#include "core/Timers.hpp"
#include "elastogen/Anderson.hpp"
#include "elastogen/Collider.hpp"
#include "elastogen/GlobalSolver.hpp"
#include "elastogen/NewtonReference.hpp"
#include "elastogen/VoxelSystem.hpp"
#include "neural/NeuralMtl.hpp"

namespace gen4d::elastogen {

struct StepStats {
  int outer = 0;               //!< RNN-1 loops run, extra ones included
  int extra = 0;               //!< loops added by the accuracy check
  int rejected = 0;            //!< accelerated iterates replaced by the plain step
  long sweeps = 0;             //!< RNN-2 sweeps summed over the loops
  double relative_change = 0;  //!< ||delta|| / ||x - x^n|| of the last loop
  double accuracy = 0;         //!< ||r_true|| / (||M(x-y)/dt^2|| + ||f_ext||)
  bool accurate = true;        //!< accuracy <= solver.accuracy_tolerance
  long contacts = 0;           //!< nodes pushed out of colliders at the end of the step
  double penetration = 0;      //!< deepest penetration (m) before that push-out
};

//! What the pre-load's static solve did.
struct PreloadStats {
  int newton_iterations = 0;
  long cg_iterations = 0;
  double relative_residual = 0;  //!< ||f_int + f|| / ||f|| at the end
};

class Elastodynamics {
 public:
  Elastodynamics(VoxelSystem& sys, const Config& cfg, PhaseTimers& timers);

  //! Positions and velocities on the ghosted box (3 per node); ghosts kept current.
  std::vector<double>& x() { return x_; }
  std::vector<double>& v() { return v_; }
  //! Resets to the rest state (x = rest positions, v = 0).
  void reset_to_rest();
  //! After x, v were overwritten on owned nodes (restart): refresh ghosts.
  void sync_ghosts();

  //! Advances from time t to t + dt.
  StepStats step(double t);

  //! Whether the deck has pre-loads: [[force]] entries active at t = 0- (start < 0 <= end).
  bool has_preloads() const;
  //! Puts the body at rest (v = 0) in static equilibrium under the pre-loads and gravity,
  //! from the rest state: Newton's method on the run's own elastic energy, each step solved
  //! by conjugate gradients (Jacobi-preconditioned, the tangent applied matrix-free as a
  //! difference of the internal forces) with exact sums, so the state does not depend on the
  //! rank count. InputError when nothing holds the body. Collective.
  PreloadStats settle_preloads();

  struct Energy {
    double kinetic = 0, elastic = 0, gravity = 0;
    double total() const { return kinetic + elastic + gravity; }
  };
  Energy energy();
  double stiffness() const { return k_; }
  //! Pose of rest point X on a kinematic region's path at time t.
  static std::array<double, 3> prescribed(const KinematicConfig& k, const Vec3d& X, double t);
  const GlobalSolver& global_solver() const { return solver_; }
  //! Total load of the [[traction]] tables active at time t on free nodes, all ranks.
  std::array<double, 3> traction_force(double t);
  //! Total external force at time t over all ranks, [[force]] and [[traction]] loads (with
  //! their curves) plus gravity on the free nodes, as a step starting at t applies it.
  //! Collective.
  std::array<double, 3> external_force(double t);

 private:
  void external_forces(double t, std::vector<double>& f) const;
  //! Gravity plus the pre-loads at t = 0- on free owned nodes (0 on the others).
  void preload_forces(std::vector<double>& f) const;
  //! y = K v on free owned nodes (K the tangent stiffness at x_, ghosts of x_ current, fint_
  //! = f_int(x_)); v's owned values are read, its ghosts refreshed; xn_ and y_ are work.
  void tangent_apply(std::vector<double>& v, std::vector<double>& y);
  //! Nodal loads of each [[traction]] table on this rank's free owned nodes.
  void build_traction_loads();
  //! Pushes free owned nodes out of the colliders (with friction) and refreshes x's ghosts.
  void resolve_contacts(StepStats& st);
  //! r = M(y - x)/dt^2 + f_int(x) on free owned nodes; returns the implicit-Euler objective
  //! 1/(2 dt^2) ||x - y||_M^2 + E(x), summed over all ranks.
  double residual(const std::vector<double>& y, std::vector<double>& r);
  parallel::ExactSum internal_forces(const std::vector<double>& x, std::vector<double>& f);
  double owned_norm(const std::vector<double>& a, const std::vector<double>* b = nullptr);

  VoxelSystem& sys_;
  const Config& cfg_;
  PhaseTimers& timers_;
  std::unique_ptr<neural::NeuralMtl> net_;  //!< set for material.target = "neural"
  double dt_, k_;
  GlobalSolver solver_;
  AndersonMixer anderson_;
  std::unique_ptr<NewtonReference> newton_;  //!< set for solver.method = "newton"
  std::vector<double> x_, v_, xn_, y_, r_, delta_, fext_, fint_, x_prev_;
  std::vector<double> force_region_mass_;
  std::vector<Collider> colliders_;
  struct NodeLoad {
    std::size_t node;  //!< ghosted index
    double f[3];       //!< N
  };
  std::vector<std::vector<NodeLoad>> traction_loads_;  //!< per [[traction]], in node order
};

}  // namespace gen4d::elastogen
