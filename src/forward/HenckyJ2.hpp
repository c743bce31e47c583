//! The diagnose forward model's von Mises return map: Hencky (logarithmic) elasticity with
//! J2 radial return and linear isotropic hardening, the same material as the MPM `von_mises`
//! model with linear hardening (src/mpm/materials/VonMises.cpp) and the same return
//! (materials/J2Return.hpp), but in the principal frame
//! of the trial left Cauchy-Green tensor b = Fe Fe^T (closed-form symmetric 3x3 eigensolver)
//! instead of a Jacobi SVD of Fe: the implicit model calls it at every Gauss point of every
//! Newton iterate, and 18 more times per point for each tangent.
//!
//! With b = sum_i l_i n_i n_i^T: e_i = log(l_i) / 2, s = 2 mu dev(e), f = |s| - sqrt(2/3)
//! (sigma_y + H eps_p). If f > 0: dg = f / (2 mu + 2 H / 3), dev(e) <- dev(e) (1 - dg / |dev e|),
//! eps_p += sqrt(2/3) dg, and Fe <- sum_i exp(e_i) / sqrt(l_i) n_i n_i^T Fe (the new elastic
//! stretch, rotation kept). tau = sum_i (2 mu e_i + lambda tr e) n_i n_i^T.
#pragma once

#include <Eigen/Dense>
#include <cmath>

#include "materials/J2Return.hpp"

namespace gen4d::forward {

struct HenckyJ2 {
  double mu = 0, lambda = 0;
  double yield_stress = 0, hardening = 0;

  //! Fe: trial elastic deformation gradient (row-major), replaced by the returned one;
  //! eps_p: equivalent plastic strain, updated; tau: Kirchhoff stress (row-major). False when
  //! Fe is singular or not finite.
  bool update(double Fe[9], double& eps_p, double tau[9]) const {
    Eigen::Matrix3d F;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) F(i, j) = Fe[3 * i + j];
    const Eigen::Matrix3d b = F * F.transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
    es.computeDirect(b);
    const Eigen::Vector3d l = es.eigenvalues();
    if (!l.allFinite() || !(l.minCoeff() > 1e-14 * l.maxCoeff())) return false;
    const Eigen::Matrix3d& N = es.eigenvectors();
    Eigen::Vector3d e = 0.5 * l.array().log().matrix();
    const double m = e.sum() / 3.0;
    const Eigen::Vector3d eh = e.array() - m;
    const double nrm = eh.norm();
    const double f = materials::j2_linear_overstress(nrm, mu, yield_stress, hardening, eps_p);
    if (f > 0 && nrm > 0) {
      const double dg = materials::j2_linear_multiplier(f, mu, hardening);
      materials::radial_return(e, eh, nrm, dg);
      eps_p += materials::kSqrt23 * dg;
      const Eigen::Vector3d r = (e.array().exp() / l.array().sqrt()).matrix();
      const Eigen::Matrix3d Fn = N * r.asDiagonal() * N.transpose() * F;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) Fe[3 * i + j] = Fn(i, j);
    }
    const double tr = e.sum();
    const Eigen::Vector3d t = (2 * mu * e.array() + lambda * tr).matrix();
    const Eigen::Matrix3d T = N * t.asDiagonal() * N.transpose();
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) tau[3 * i + j] = T(i, j);
    return true;
  }
};

}  // namespace gen4d::forward
