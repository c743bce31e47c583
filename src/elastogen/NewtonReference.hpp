//! Reference solver for the implicit-Euler step: Newton's method on the same voxel
//! discretisation and true material energy (PETSc SNES with line search, CG + GAMG), used as
//! ground truth for ElastoGen's accuracy and selectable with solver.method = "newton".
#pragma once

#include <petscsnes.h>

#include <functional>
#include <vector>

#include "core/Timers.hpp"
#include "elastogen/VoxelSystem.hpp"

namespace gen4d::elastogen {

struct NewtonStats {
  int newton_iterations = 0;
  long krylov_iterations = 0;
  bool converged = false;
};

class NewtonReference {
 public:
  //! r(x) must write M(y - x)/dt^2 + f_int(x) on owned free nodes for x on the ghosted box
  //! (ghosts current); it is the negative gradient of the implicit-Euler objective.
  using Residual = std::function<void(const std::vector<double>& x, std::vector<double>& r)>;

  //! Pointwise first Piola stress of the true material (returns the energy density).
  using Stress = std::function<double(const double* F, double* P)>;

  NewtonReference(VoxelSystem& sys, Stress stress, double dt, PhaseTimers& timers);
  ~NewtonReference();
  NewtonReference(const NewtonReference&) = delete;
  NewtonReference& operator=(const NewtonReference&) = delete;

  //! Solves r(x) = 0 from the initial x (ghosted box, updated in place, ghosts current);
  //! held nodes keep their values. The Jacobian M/dt^2 + sum_q w G_q^T (dP/dF) G_q is
  //! assembled with the stress tangent from central differences of P at each Gauss point.
  //! PETSc options with prefix -newton_ (PETSC_OPTIONS) override every solver choice.
  NewtonStats solve(std::vector<double>& x, const Residual& residual, parallel::Halo& halo);

 private:
  static PetscErrorCode form_function(SNES snes, Vec X, Vec F, void* ctx);
  static PetscErrorCode form_jacobian(SNES snes, Vec X, Mat J, Mat P, void* ctx);
  void assemble_jacobian(Mat J);
  void unpack(Vec X, std::vector<double>& x) const;

  VoxelSystem& sys_;
  PhaseTimers& timers_;
  SNES snes_ = nullptr;
  Stress stress_;
  double inv_dt2_;
  Mat J_ = nullptr;
  Vec X_ = nullptr;
  // Per-solve state for the callback.
  const Residual* residual_ = nullptr;
  parallel::Halo* halo_ = nullptr;
  std::vector<double>* hold_ = nullptr;
  std::vector<double> work_x_, work_r_;
};

}  // namespace gen4d::elastogen
