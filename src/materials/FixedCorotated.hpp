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
struct FixedCorotated : LameLaw<FixedCorotated> {
  static constexpr const char* name = "fixed_corotated";

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

  //! The stress Jacobian D[3i+j][3k+l] = dP_ij/dF_kl from one SVD (implicit solvers' tangent):
  //!   dP = 2 mu (dF - dR) + lambda (cof F : dF) cof F + lambda (J - 1) d(cof F).
  //! With F = R S (S = V diag(sigma) V^T symmetric) and W = R^T dR skew, the skew part of
  //! R^T dF is W S + S W = [(tr S - S) w]x, so dR = R [w]x with w = (tr S - S)^-1 a, a the axial
  //! vector of R^T dF - dF^T R, and (tr S - S)^-1 = V diag(1 / (sigma_j + sigma_k)) V^T. Where
  //! sigma_j + sigma_k vanishes (an element flat-inverted in two directions) R has no
  //! derivative; that direction's rotation term is dropped.
  GEN4D_HD void pk1_jacobian(const Mat3& F, double D[9][9]) const {
    Mat3 U, V;
    Vec3 s;
    svd3(F, U, s, V);
    const Mat3 R = U * transpose(V);
    const Mat3 C = cofactor(F);
    const double J = det(F);
    const double tiny = 1e-12 * (std::fabs(s[0]) + std::fabs(s[1]) + std::fabs(s[2]));
    Vec3 inv;
    for (int i = 0; i < 3; ++i) {
      const double d = s[(i + 1) % 3] + s[(i + 2) % 3];
      inv[i] = std::fabs(d) > tiny ? 1.0 / d : 0.0;
    }
    const Mat3 A = V * diag3(inv) * transpose(V);
    for (int k = 0; k < 3; ++k)
      for (int l = 0; l < 3; ++l) {
        // M = R^T E_kl: M(a, b) = R(k, a) [b == l]; a = axial(M - M^T).
        Vec3 m{{0, 0, 0}};
        m[0] = (l == 1 ? R(k, 2) : 0.0) - (l == 2 ? R(k, 1) : 0.0);
        m[1] = (l == 2 ? R(k, 0) : 0.0) - (l == 0 ? R(k, 2) : 0.0);
        m[2] = (l == 0 ? R(k, 1) : 0.0) - (l == 1 ? R(k, 0) : 0.0);
        const Vec3 w = A * m;
        const Mat3 Wx{{0, -w[2], w[1], w[2], 0, -w[0], -w[1], w[0], 0}};
        const Mat3 dR = R * Wx;
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) {
            // d cof_ij / dF_kl = eps_ikn eps_jlq F_nq (zero unless i != k and j != l).
            double dcof = 0;
            if (i != k && j != l) {
              const int n = 3 - i - k, q = 3 - j - l;
              const double e1 = ((k - i + 3) % 3 == 1) ? 1.0 : -1.0;  // eps_ikn
              const double e2 = ((l - j + 3) % 3 == 1) ? 1.0 : -1.0;  // eps_jlq
              dcof = e1 * e2 * F(n, q);
            }
            const double dF = (i == k && j == l) ? 1.0 : 0.0;
            D[3 * i + j][3 * k + l] =
                2.0 * mu * (dF - dR(i, j)) + lambda * C(k, l) * C(i, j) + lambda * (J - 1.0) * dcof;
          }
      }
  }

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
