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
