#include "elastogen/GlobalSolver.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <tuple>

#include "core/Log.hpp"

namespace gen4d::elastogen {

namespace {
constexpr int kLanczosSteps = 24;          //!< set-up iterations of the lambda_max estimate
constexpr double kChebyshevSafety = 1.05;  //!< lambda_max = safety * largest Ritz value

}  // namespace

GlobalSolver::GlobalSolver(VoxelSystem& sys, const SolverConfig& cfg, double k, double dt,
                           PhaseTimers& timers)
    : sys_(sys),
      cfg_(cfg),
      k_(k),
      inv_dt2_(1.0 / (dt * dt)),
      timers_(timers),
      halo_(sys.grid(), 3),
      red_(sys.grid().comm()) {
  sys_.diagonal(k_, inv_dt2_, diag_);
  const std::size_t n = 3 * sys_.ghosted().size();
  ad_.assign(n, 0.0);
  res_.assign(n, 0.0);
  z_.assign(n, 0.0);
  p_.assign(n, 0.0);
  if (cfg_.subspace_modes > 0) build_subspace();
  if (cfg_.relaxation == "chebyshev") estimate_spectrum();
}

double GlobalSolver::owned_norm2(const std::vector<double>& a) {
  parallel::ExactSum s;
  reduce_owned(sys_.owned(), sys_.ghosted(), 1, &s,
               [&](std::size_t n, long, long, long, parallel::ExactSum* acc) {
                 for (int d = 0; d < 3; ++d) acc[0].add(a[3 * n + d] * a[3 * n + d]);
               });
  double g = 0;
  PhaseTimers::Scope t(timers_, "reduction");
  red_.sum(&s, &g, 1);
  return g;
}

void GlobalSolver::build_subspace() {
  // Cosine products over the node grid: the lowest-frequency modes of the box's discrete
  // Laplacian with free (Neumann) faces; mode (0,0,0) is the rigid translation.
  const auto& nn = sys_.grid().global_nodes();
  const int max_freq = 8;
  for (int d = 0; d < 3; ++d) {
    cos_[d].assign(max_freq, std::vector<double>(nn[d]));
    for (int f = 0; f < max_freq; ++f)
      for (long i = 0; i < nn[d]; ++i)
        cos_[d][f][i] =
            std::cos(M_PI * f * static_cast<double>(i) / static_cast<double>(nn[d] - 1));
  }
  std::vector<std::tuple<double, int, int, int>> cand;
  for (int a = 0; a < max_freq; ++a)
    for (int b = 0; b < max_freq; ++b)
      for (int c = 0; c < max_freq; ++c) {
        const double wave = std::pow(a / double(nn[0] - 1), 2) +
                            std::pow(b / double(nn[1] - 1), 2) + std::pow(c / double(nn[2] - 1), 2);
        cand.emplace_back(wave, a, b, c);
      }
  std::sort(cand.begin(), cand.end());
  const int K = std::min<int>(cfg_.subspace_modes, static_cast<int>(cand.size()));
  for (int m = 0; m < K; ++m)
    modes_.push_back({std::get<1>(cand[m]), std::get<2>(cand[m]), std::get<3>(cand[m])});

  // Phi^T A Phi, one operator application per mode and one fused reduction for all K^2
  // entries. The modes live in component 0 only: the operator acts alike on x, y and z.
  const Box& G = sys_.ghosted();
  const auto& free = sys_.free_mask();
  std::vector<double> phi(3 * G.size(), 0.0), aphi(3 * G.size(), 0.0);
  std::vector<parallel::ExactSum> local(static_cast<std::size_t>(K * K));
  for (int j = 0; j < K; ++j) {
    for (long k = G.start[2]; k < G.start[2] + G.count[2]; ++k)
      for (long jj = G.start[1]; jj < G.start[1] + G.count[1]; ++jj)
        for (long i = G.start[0]; i < G.start[0] + G.count[0]; ++i) {
          const std::size_t n = G.index(i, jj, k);
          phi[3 * n] = free[n] ? mode_value(modes_[j], i, jj, k) : 0.0;
        }
    sys_.apply(k_, inv_dt2_, phi.data(), aphi.data());
    for_owned(sys_.owned(), G, [&](std::size_t n, long i, long jj, long k) {
      if (!free[n]) return;
      for (int m = 0; m < K; ++m)
        local[m * K + j].add(mode_value(modes_[m], i, jj, k) * aphi[3 * n]);
    });
  }
  Eigen::MatrixXd S(K, K);
  red_.sum(local.data(), S.data(), local.size());
  S = 0.5 * (S + S.transpose()).eval();
  // Pseudo-inverse: modes can become dependent once masked to the object.
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(S);
  const double cutoff = 1e-12 * eig.eigenvalues().cwiseAbs().maxCoeff();
  Eigen::VectorXd inv =
      eig.eigenvalues().unaryExpr([&](double l) { return l > cutoff ? 1.0 / l : 0.0; });
  subspace_pinv_ = eig.eigenvectors() * inv.asDiagonal() * eig.eigenvectors().transpose();
}

void GlobalSolver::subspace_start(const std::vector<double>& r, std::vector<double>& delta) {
  const int K = static_cast<int>(modes_.size());
  const Box& G = sys_.ghosted();
  const auto& free = sys_.free_mask();
  std::vector<parallel::ExactSum> local(static_cast<std::size_t>(3 * K));
  {
    PhaseTimers::Scope t(timers_, "subspace");
    reduce_owned(sys_.owned(), G, local.size(), local.data(),
                 [&](std::size_t n, long i, long j, long k, parallel::ExactSum* acc) {
                   if (!free[n]) return;
                   for (int m = 0; m < K; ++m) {
                     const double phi = mode_value(modes_[m], i, j, k);
                     for (int d = 0; d < 3; ++d) acc[3 * m + d].add(phi * r[3 * n + d]);
                   }
                 });
  }
  Eigen::MatrixXd rhs(3, K);
  {
    PhaseTimers::Scope t(timers_, "reduction");
    red_.sum(local.data(), rhs.data(), local.size());
  }
  PhaseTimers::Scope t(timers_, "subspace");
  const Eigen::MatrixXd coef = subspace_pinv_ * rhs.transpose();  // K x 3
  parallel_owned(G, G, [&](std::size_t n, long i, long j, long k) {
    double acc[3] = {0, 0, 0};
    if (free[n])
      for (int m = 0; m < K; ++m) {
        const double phi = mode_value(modes_[m], i, j, k);
        for (int d = 0; d < 3; ++d) acc[d] += phi * coef(m, d);
      }
    for (int d = 0; d < 3; ++d) delta[3 * n + d] = acc[d];
  });
}

InnerStats GlobalSolver::solve(const std::vector<double>& r, std::vector<double>& delta) {
  const double rnorm = std::sqrt(owned_norm2(r));
  delta.assign(r.size(), 0.0);
  if (rnorm == 0.0) return {};
  if (!modes_.empty()) subspace_start(r, delta);
  if (cfg_.relaxation == "cg") return cg(r, delta, rnorm);
  if (cfg_.relaxation == "chebyshev") return chebyshev(r, delta, rnorm);
  return jacobi(r, delta, rnorm);
}

InnerStats GlobalSolver::jacobi(const std::vector<double>& r, std::vector<double>& delta,
                                double rnorm) {
  const Box& G = sys_.ghosted();
  const double omega = cfg_.jacobi_omega;
  const int check_every = 8;
  InnerStats st;
  st.relative_residual = 1.0;
  // Sweeps alternate between delta and a second buffer (Jacobi reads only old values);
  // the residual is stored only on the sweeps that check it.
  tmp_.resize(delta.size());
  std::vector<double>* cur = &delta;
  std::vector<double>* next = &tmp_;
  for (int s = 1; s <= cfg_.max_sweeps; ++s) {
    {
      PhaseTimers::Scope t(timers_, "halo");
      halo_.gather(cur->data());
    }
    const bool check = s % check_every == 0 || s == cfg_.max_sweeps;
    {
      PhaseTimers::Scope t(timers_, "sweeps");
      sys_.jacobi_sweep(k_, inv_dt2_, omega, r.data(), diag_.data(), cur->data(), next->data(),
                        check ? res_.data() : nullptr);
    }
    std::swap(cur, next);
    st.sweeps = s;
    if (check) {
      st.relative_residual = std::sqrt(owned_norm2(res_)) / rnorm;
      if (st.relative_residual < cfg_.inner_tolerance) break;
    }
  }
  if (cur != &delta) {
    PhaseTimers::Scope t(timers_, "sweeps");
    parallel_owned(sys_.owned(), G, [&](std::size_t n, long, long, long) {
      for (int d = 0; d < 3; ++d) delta[3 * n + d] = (*cur)[3 * n + d];
    });
  }
  PhaseTimers::Scope t(timers_, "halo");
  halo_.gather(delta.data());
  return st;
}

namespace {
//! Deterministic pseudo-random value in [-1, 1) of a global node index (splitmix64), so the
//! Lanczos start vector is the same whatever the decomposition.
double hashed_unit(std::uint64_t z) {
  z += 0x9e3779b97f4a7c15ULL;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  z ^= z >> 31;
  return static_cast<double>(z >> 11) * 0x1.0p-52 - 1.0;
}
}  // namespace

void GlobalSolver::estimate_spectrum() {
  // Lanczos on D^-1 A through Jacobi-preconditioned CG from a hashed random right-hand side:
  // the CG coefficients give the Lanczos tridiagonal T (Saad, Iterative Methods, sec. 6.7.3),
  // whose extreme eigenvalues (Ritz values) approach those of D^-1 A from inside. The operator
  // is the same for x, y and z, so component 0 carries the iteration. All dot products use
  // the exact reducer: T, and so the interval, is bit-identical on every rank and rank count.
  const Box& G = sys_.ghosted();
  const Box& O = sys_.owned();
  const auto& free = sys_.free_mask();
  const auto& nn = sys_.grid().global_nodes();
  std::fill(res_.begin(), res_.end(), 0.0);
  std::fill(z_.begin(), z_.end(), 0.0);
  std::fill(p_.begin(), p_.end(), 0.0);
  parallel::ExactSum rz_l;
  for_owned(O, G, [&](std::size_t n, long i, long j, long k) {
    if (!free[n]) return;
    res_[3 * n] = hashed_unit(static_cast<std::uint64_t>((k * nn[1] + j) * nn[0] + i));
    z_[3 * n] = p_[3 * n] = res_[3 * n] / diag_[n];
    rz_l.add(res_[3 * n] * z_[3 * n]);
  });
  double rz = 0;
  red_.sum(&rz_l, &rz, 1);
  const double rz0 = rz;
  std::vector<double> alpha, beta;
  for (int it = 0; it < kLanczosSteps && rz > 1e-28 * rz0; ++it) {
    halo_.gather(p_.data());
    sys_.apply(k_, inv_dt2_, p_.data(), ad_.data());
    parallel::ExactSum pap_l;
    for_owned(O, G, [&](std::size_t n, long, long, long) { pap_l.add(p_[3 * n] * ad_[3 * n]); });
    double pap = 0;
    red_.sum(&pap_l, &pap, 1);
    if (!(pap > 0)) break;
    const double a = rz / pap;
    parallel::ExactSum rz_new_l;
    for_owned(O, G, [&](std::size_t n, long, long, long) {
      res_[3 * n] -= a * ad_[3 * n];
      z_[3 * n] = res_[3 * n] / diag_[n];
      rz_new_l.add(res_[3 * n] * z_[3 * n]);
    });
    double rz_new = 0;
    red_.sum(&rz_new_l, &rz_new, 1);
    const double b = rz_new / rz;
    rz = rz_new;
    for_owned(O, G,
              [&](std::size_t n, long, long, long) { p_[3 * n] = z_[3 * n] + b * p_[3 * n]; });
    alpha.push_back(a);
    beta.push_back(b);
  }
  std::fill(res_.begin(), res_.end(), 0.0);
  std::fill(z_.begin(), z_.end(), 0.0);
  std::fill(p_.begin(), p_.end(), 0.0);
  std::fill(ad_.begin(), ad_.end(), 0.0);
  const int m = static_cast<int>(alpha.size());
  if (m == 0) {  // no free node (or an operator without positive curvature): nothing to solve
    ritz_min_ = ritz_max_ = 1.0;
  } else {
    Eigen::MatrixXd T = Eigen::MatrixXd::Zero(m, m);
    for (int j = 0; j < m; ++j) {
      T(j, j) = 1.0 / alpha[j] + (j > 0 ? beta[j - 1] / alpha[j - 1] : 0.0);
      if (j + 1 < m) T(j, j + 1) = T(j + 1, j) = std::sqrt(beta[j]) / alpha[j];
    }
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(T, Eigen::EigenvaluesOnly);
    ritz_min_ = eig.eigenvalues()(0);
    ritz_max_ = eig.eigenvalues()(m - 1);
  }
  // Upper end: Ritz values lie inside the spectrum, so the largest is raised by a safety
  // factor (an eigenvalue above lmax would be amplified). Lower end: the subspace start has
  // already removed the smoothest error, and an eigenvalue below lmin is damped more slowly
  // but never amplified, so lmin = chebyshev_ratio * lmax (measured best near 0.05 at the
  // default inner tolerance); chebyshev_ratio = 0 takes the smallest Ritz value instead, the
  // interval of the whole spectrum, which wins for tight inner tolerances.
  cheb_lmax_ = kChebyshevSafety * ritz_max_;
  cheb_lmin_ = cfg_.chebyshev_ratio > 0 ? cfg_.chebyshev_ratio * cheb_lmax_ : ritz_min_;
  log::info(
      "Chebyshev relaxation: D^-1 A eigenvalues in [{:.4g}, {:.4g}] ({} Lanczos steps, "
      "Ritz values {:.4g} to {:.4g})",
      cheb_lmin_, cheb_lmax_, m, ritz_min_, ritz_max_);
}

InnerStats GlobalSolver::chebyshev(const std::vector<double>& r, std::vector<double>& delta,
                                   double rnorm) {
  // Chebyshev semi-iteration on D^-1 A with eigenvalue interval [lmin, lmax] (Saad, Iterative
  // Methods, Alg. 12.1, preconditioned by D): after s sweeps the error is multiplied by the
  // scaled Chebyshev polynomial of degree s, the smallest on [lmin, lmax] among polynomials
  // with p(0) = 1. The residual is recomputed from delta each sweep (one operator application
  // and one halo exchange per sweep, as for Jacobi); the update d lives in p_.
  const Box& G = sys_.ghosted();
  const auto& free = sys_.free_mask();
  const double theta = 0.5 * (cheb_lmax_ + cheb_lmin_), half = 0.5 * (cheb_lmax_ - cheb_lmin_);
  const double sigma = theta / half;
  double rho = 1.0 / sigma;
  const int check_every = 8;
  InnerStats st;
  st.relative_residual = 1.0;
  for (int s = 1; s <= cfg_.max_sweeps; ++s) {
    double c_old = 0.0, c_res = 1.0 / theta;  // d = c_old d + c_res D^-1 (r - A delta)
    if (s > 1) {
      const double rho_new = 1.0 / (2.0 * sigma - rho);
      c_old = rho_new * rho;
      c_res = 2.0 * rho_new / half;
      rho = rho_new;
    }
    {
      PhaseTimers::Scope t(timers_, "halo");
      halo_.gather(delta.data());
    }
    {
      PhaseTimers::Scope t(timers_, "sweeps");
      sys_.apply(k_, inv_dt2_, delta.data(), ad_.data());
      parallel_owned(sys_.owned(), G, [&](std::size_t n, long, long, long) {
        if (!free[n]) return;
        for (int d = 0; d < 3; ++d) {
          const std::size_t q = 3 * n + d;
          const double rr = r[q] - ad_[q];
          res_[q] = rr;
          p_[q] = c_old * p_[q] + c_res * rr / diag_[n];
          delta[q] += p_[q];
        }
      });
    }
    st.sweeps = s;
    if (s % check_every == 0 || s == cfg_.max_sweeps) {
      st.relative_residual = std::sqrt(owned_norm2(res_)) / rnorm;
      if (st.relative_residual < cfg_.inner_tolerance) break;
    }
  }
  PhaseTimers::Scope t(timers_, "halo");
  halo_.gather(delta.data());
  return st;
}

InnerStats GlobalSolver::cg(const std::vector<double>& r, std::vector<double>& delta,
                            double rnorm) {
  // Jacobi-preconditioned conjugate gradients on the same matrix-free operator.
  const Box& G = sys_.ghosted();
  const Box& O = sys_.owned();
  const auto& free = sys_.free_mask();
  InnerStats st;
  {
    PhaseTimers::Scope t(timers_, "halo");
    halo_.gather(delta.data());
  }
  sys_.apply(k_, inv_dt2_, delta.data(), ad_.data());
  parallel::ExactSum rz0;
  for_owned(O, G, [&](std::size_t n, long, long, long) {
    for (int d = 0; d < 3; ++d) {
      const std::size_t q = 3 * n + d;
      res_[q] = free[n] ? r[q] - ad_[q] : 0.0;
      z_[q] = res_[q] / diag_[n];
      p_[q] = z_[q];
      rz0.add(res_[q] * z_[q]);
    }
  });
  double rz = 0;
  red_.sum(&rz0, &rz, 1);
  st.relative_residual = std::sqrt(owned_norm2(res_)) / rnorm;
  for (int s = 1; s <= cfg_.max_sweeps && st.relative_residual >= cfg_.inner_tolerance; ++s) {
    {
      PhaseTimers::Scope t(timers_, "halo");
      halo_.gather(p_.data());
    }
    parallel::ExactSum pap_l;
    {
      PhaseTimers::Scope t(timers_, "sweeps");
      sys_.apply(k_, inv_dt2_, p_.data(), ad_.data());
      for_owned(O, G, [&](std::size_t n, long, long, long) {
        for (int d = 0; d < 3; ++d) pap_l.add(p_[3 * n + d] * ad_[3 * n + d]);
      });
    }
    double pap = 0;
    {
      PhaseTimers::Scope t(timers_, "reduction");
      red_.sum(&pap_l, &pap, 1);
    }
    if (!(pap > 0)) break;
    const double alpha = rz / pap;
    parallel::ExactSum fused[2];  // r.z and r.r in one reduction
    {
      PhaseTimers::Scope t(timers_, "sweeps");
      for_owned(O, G, [&](std::size_t n, long, long, long) {
        for (int d = 0; d < 3; ++d) {
          const std::size_t q = 3 * n + d;
          delta[q] += alpha * p_[q];
          res_[q] -= alpha * ad_[q];
          z_[q] = res_[q] / diag_[n];
          fused[0].add(res_[q] * z_[q]);
          fused[1].add(res_[q] * res_[q]);
        }
      });
    }
    double g[2];
    {
      PhaseTimers::Scope t(timers_, "reduction");
      red_.sum(fused, g, 2);
    }
    const double beta = g[0] / rz;
    rz = g[0];
    for_owned(O, G, [&](std::size_t n, long, long, long) {
      for (int d = 0; d < 3; ++d) p_[3 * n + d] = z_[3 * n + d] + beta * p_[3 * n + d];
    });
    st.sweeps = s;
    st.relative_residual = std::sqrt(g[1]) / rnorm;
  }
  PhaseTimers::Scope t(timers_, "halo");
  halo_.gather(delta.data());
  return st;
}

}  // namespace gen4d::elastogen
