//! RNN-2 of ElastoGen: solves (M/dt^2 + k L) delta = r matrix-free, started from the
//! low-frequency subspace solution and refined by damped Jacobi sweeps, Chebyshev-accelerated
//! Jacobi sweeps, or CG, with one halo exchange per sweep.
#pragma once

#include <Eigen/Dense>

#include <vector>

#include "core/Config.hpp"
#include "core/Timers.hpp"
#include "elastogen/VoxelSystem.hpp"

namespace gen4d::elastogen {

struct InnerStats {
  int sweeps = 0;
  double relative_residual = 0;  //!< ||r - A delta|| / ||r|| at exit
};

class GlobalSolver {
 public:
  GlobalSolver(VoxelSystem& sys, const SolverConfig& cfg, double k, double dt, PhaseTimers& timers);

  //! r: right-hand side on owned nodes (zero on non-free); delta: result on the ghosted box,
  //! ghosts current on return.
  InnerStats solve(const std::vector<double>& r, std::vector<double>& delta);

  int subspace_modes() const { return static_cast<int>(modes_.size()); }
  //! Chebyshev interval [lmin, lmax] for the eigenvalues of D^-1 A (0, 0 unless
  //! relaxation = "chebyshev"), and the largest Lanczos Ritz value it was built from.
  double chebyshev_lmin() const { return cheb_lmin_; }
  double chebyshev_lmax() const { return cheb_lmax_; }
  double lanczos_lmax() const { return ritz_max_; }
  parallel::Reducer& reducer() { return red_; }
  parallel::Halo& halo() { return halo_; }

 private:
  struct Mode {
    int a, b, c;
  };
  void build_subspace();
  double mode_value(const Mode& m, long i, long j, long k) const {
    return cos_[0][m.a][i] * cos_[1][m.b][j] * cos_[2][m.c][k];
  }
  void subspace_start(const std::vector<double>& r, std::vector<double>& delta);
  InnerStats jacobi(const std::vector<double>& r, std::vector<double>& delta, double rnorm);
  InnerStats chebyshev(const std::vector<double>& r, std::vector<double>& delta, double rnorm);
  void estimate_spectrum();
  InnerStats cg(const std::vector<double>& r, std::vector<double>& delta, double rnorm);
  double owned_norm2(const std::vector<double>& a);

  VoxelSystem& sys_;
  SolverConfig cfg_;
  double k_, inv_dt2_;
  PhaseTimers& timers_;
  parallel::Halo halo_;
  parallel::Reducer red_;
  std::vector<double> diag_;
  std::vector<double> ad_, res_, z_, p_, tmp_;  // work arrays on the ghosted box
  std::vector<Mode> modes_;
  std::vector<std::vector<double>> cos_[3];  // per axis: per frequency, per global index
  Eigen::MatrixXd subspace_pinv_;            // (Phi^T A Phi)^+, identical on every rank
  double cheb_lmin_ = 0, cheb_lmax_ = 0, ritz_min_ = 0, ritz_max_ = 0;
};

}  // namespace gen4d::elastogen
