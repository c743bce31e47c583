//! Stable (inversion-safe) Neo-Hookean elasticity, pointwise and device-callable.
#pragma once

#include <cmath>

#include "materials/Hd.hpp"
#include "materials/Lame.hpp"
#include "materials/Mat3.hpp"
#include "materials/Registry.hpp"

namespace gen4d::materials {

//! Smith, de Goes and Kim 2018: psi = mu/2 (I_C - 3) + lambda/2 (J - alpha)^2
//! - mu/2 log(I_C + 1), shifted so psi(I) = 0. Unlike the classic log(J) form it is finite
//! and smooth for every F, inverted and degenerate ones included.
//! Rest stability gives alpha = 1 + 3 mu / (4 lambda). Linearising P at F = I gives
//! (3 mu / 4)(H + H^T) + (lambda - 5 mu / 8) tr(H) I, so matching linear elasticity with the
//! Lame pair (mu_L, lambda_L) needs mu = 4/3 mu_L and lambda = lambda_L + 5/6 mu_L.
struct NeoHookean {
  static constexpr const char* name = "stable_neo_hookean";
  double mu;      //!< model parameter (4/3 of the Lame shear modulus)
  double lambda;  //!< model parameter (Lame lambda + 5/6 Lame mu)

  static NeoHookean from_young_poisson(double youngs_modulus, double poisson_ratio) {
    const Lame l = lame_from_young_poisson(youngs_modulus, poisson_ratio);
    return NeoHookean{4.0 / 3.0 * l.mu, l.lambda + 5.0 / 6.0 * l.mu};
  }
  GEN4D_HD double alpha() const { return 1.0 + 0.75 * mu / lambda; }

  GEN4D_HD double energy(const Mat3& F) const {
    const double ic = frobenius_dot(F, F), J = det(F), a = alpha();
    const double rest = 0.5 * lambda * (1.0 - a) * (1.0 - a) - 0.5 * mu * std::log(4.0);
    return 0.5 * mu * (ic - 3.0) + 0.5 * lambda * (J - a) * (J - a) -
           0.5 * mu * std::log(ic + 1.0) - rest;
  }
  //! P = mu (1 - 1/(I_C + 1)) F + lambda (J - alpha) cof(F), with lambda (J - alpha) written
  //! as lambda (J - 1) - 3 mu / 4 so the rest stress cancels exactly.
  GEN4D_HD Mat3 pk1(const Mat3& F) const {
    const double ic = frobenius_dot(F, F), J = det(F);
    return (mu * (1.0 - 1.0 / (ic + 1.0))) * F + (lambda * (J - 1.0) - 0.75 * mu) * cofactor(F);
  }
  GEN4D_HD double energy_and_pk1(const Mat3& F, Mat3& P) const {
    P = pk1(F);
    return energy(F);
  }
  //! Bound on the largest eigenvalue of dP/dF for |sigma_i - 1| <= stretch = s, by the
  //! triangle inequality over its three parts (as for the corotated model):
  //!   mu-part  mu (1 - 1/(I_C+1)) I + 2 mu/(I_C+1)^2 F (x) F       <= 1.5 mu,
  //!   lambda g g^T with g = cof(F), |g|^2 <= 3 (1+s)^4,
  //!   lambda (J - alpha) d cof/dF, spectral radius <= |J - alpha| 2 (1+s),
  //! with |J - alpha| <= max(alpha - (1-s)^3, (1+s)^3 - alpha) since alpha >= 1.
  GEN4D_HD double projection_stiffness(double stretch = 0.1) const {
    const double a = 1.0 + stretch, b = 1.0 - stretch, al = alpha();
    const double dj = (al - b * b * b) > (a * a * a - al) ? (al - b * b * b) : (a * a * a - al);
    const double l = std::fabs(lambda);
    return 1.5 * mu + l * 3.0 * a * a * a * a + l * 2.0 * a * dj;
  }
};

GEN4D_REGISTER_MATERIAL(NeoHookean);

}  // namespace gen4d::materials
