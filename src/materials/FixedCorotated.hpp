//! Fixed corotated elasticity (Stomakhin et al. 2012), pointwise and device-callable.
#pragma once

#include <cmath>

#include "materials/Hd.hpp"
#include "materials/Lame.hpp"
#include "materials/Mat3.hpp"
#include "materials/Registry.hpp"
#include "materials/Svd3.hpp"

namespace gen4d::materials {

//! Stretch range |sigma_i - 1| <= s over which projection_stiffness() bounds the stress
//! Jacobian by default; beyond it the outer accuracy check of the solver takes over.
inline constexpr double kProjectionDesignStretch = 0.1;

//! psi(F) = mu ||F - R||_F^2 + lambda/2 (J - 1)^2 with R the rotation of the signed SVD, so the
//! model stays defined and restoring for inverted elements (det F < 0).
struct FixedCorotated {
  static constexpr const char* name = "corotated";
  double mu;
  double lambda;

  //! Lame parameters from the deck values; InputError on E <= 0 or nu outside (-1, 0.5).
  static FixedCorotated from_young_poisson(double youngs_modulus, double poisson_ratio) {
    const Lame lame = lame_from_young_poisson(youngs_modulus, poisson_ratio);
    return FixedCorotated{lame.mu, lame.lambda};
  }

  //! Energy density with the signed singular values: mu sum (sigma_i - 1)^2 = mu ||F - R||^2.
  GEN4D_HD double energy_from_singular_values(const Vec3& s, double J) const {
    const double d0 = s[0] - 1.0, d1 = s[1] - 1.0, d2 = s[2] - 1.0;
    return mu * (d0 * d0 + d1 * d1 + d2 * d2) + 0.5 * lambda * (J - 1.0) * (J - 1.0);
  }
  GEN4D_HD double energy(const Mat3& F) const {
    Mat3 U, V;
    Vec3 s;
    svd3(F, U, s, V);
    return energy_from_singular_values(s, det(F));
  }

  //! P = 2 mu (F - R) + lambda (J - 1) cof(F); cof(F) = J F^{-T} but stays defined at J = 0.
  //! (The derivative of R drops out: (F - R) : dR = 0 because R^T (F - R) is symmetric.)
  GEN4D_HD Mat3 pk1(const Mat3& F, const Mat3& R) const {
    const double J = det(F);
    return 2.0 * mu * (F - R) + (lambda * (J - 1.0)) * cofactor(F);
  }
  GEN4D_HD Mat3 pk1(const Mat3& F) const { return pk1(F, polar_rotation(F)); }

  //! Energy and stress from one SVD (the solver's per-quadrature-point call).
  GEN4D_HD double energy_and_pk1(const Mat3& F, Mat3& P) const {
    Mat3 U, V;
    Vec3 s;
    svd3(F, U, s, V);
    P = pk1(F, U * transpose(V));
    return energy_from_singular_values(s, det(F));
  }

  //! k for the projective-dynamics local model k/2 ||F - p||^2 with p = F - P(F)/k.
  //
  // That local-global iteration is a quasi-Newton method whose constant matrix replaces the
  // stress Jacobian H = dP/dF (9x9, symmetric) by k I. Linearised, it converges when
  // 0 < H < 2k and decreases the energy monotonically (the quadratic majorises psi) when
  // H <= k, so k must bound the largest eigenvalue of H over the F the solver visits.
  // In the SVD frame H splits into (Smith et al. 2019, "Analytic eigensystems"), with
  // psi_i = dpsi/dsigma_i = 2 mu (sigma_i - 1) + lambda (J - 1) J / sigma_i:
  //   scaling block 2 mu I + lambda (g g^T + (J - 1) K), g_i = J / sigma_i, K_ij = sigma_k (i!=j);
  //   twist  (psi_i - psi_j) / (sigma_i - sigma_j) = 2 mu - lambda (J - 1) sigma_k;
  //   flip   (psi_i + psi_j) / (sigma_i + sigma_j) = 2 mu (1 - 2 / (sigma_i + sigma_j))
  //                                                 + lambda (J - 1) sigma_k.
  // At rest (F = I) that is 0 (flip), 2 mu (twist, deviatoric) and 2 mu + 3 lambda (dilation),
  // so 2 mu + 3 lambda is exact there but is exceeded by any stretch (|g|^2 grows as J^2).
  // For |sigma_i - 1| <= s: |g|^2 <= 3 (1+s)^4, |J - 1| <= (1+s)^3 - 1, rho(K) <= 2 (1+s), hence
  //   lambda_max(H) <= 2 mu + max(lambda, 0) 3 (1+s)^4 + |lambda| 2 (1+s) ((1+s)^3 - 1),
  // with equality under uniform stretch 1+s when lambda >= 0. With s = 0.1 this is
  // 2 mu + 5.12 lambda; a larger k only slows the deviatoric modes (rate ~ 1 - 2 mu / k).
  GEN4D_HD double projection_stiffness(double stretch = kProjectionDesignStretch) const {
    const double a = 1.0 + stretch;
    const double volume_change = a * a * a - 1.0;
    const double lambda_pos = lambda > 0.0 ? lambda : 0.0;
    return 2.0 * mu + lambda_pos * 3.0 * a * a * a * a +
           std::fabs(lambda) * 2.0 * a * volume_change;
  }
};

GEN4D_REGISTER_MATERIAL(FixedCorotated);

}  // namespace gen4d::materials
