//! Saint Venant-Kirchhoff elasticity, pointwise and device-callable.
#pragma once

#include "materials/Hd.hpp"
#include "materials/Lame.hpp"
#include "materials/Mat3.hpp"
#include "materials/Registry.hpp"

namespace gen4d::materials {

//! psi = mu ||E||^2 + lambda/2 tr(E)^2 with the Green strain E = (F^T F - I)/2. Exact for
//! large rotations, but it softens under strong compression (it is not inversion-safe).
struct StVK {
  static constexpr const char* name = "stvk";
  double mu;
  double lambda;

  static StVK from_young_poisson(double youngs_modulus, double poisson_ratio) {
    const Lame l = lame_from_young_poisson(youngs_modulus, poisson_ratio);
    return StVK{l.mu, l.lambda};
  }
  GEN4D_HD static Mat3 green_strain(const Mat3& F) {
    return 0.5 * (transpose(F) * F - identity3());
  }
  GEN4D_HD double energy(const Mat3& F) const {
    const Mat3 E = green_strain(F);
    const double tr = E.a[0] + E.a[4] + E.a[8];
    return mu * frobenius_dot(E, E) + 0.5 * lambda * tr * tr;
  }
  //! P = F (2 mu E + lambda tr(E) I).
  GEN4D_HD Mat3 pk1(const Mat3& F) const {
    const Mat3 E = green_strain(F);
    const double tr = E.a[0] + E.a[4] + E.a[8];
    return F * (2.0 * mu * E + (lambda * tr) * identity3());
  }
  GEN4D_HD double energy_and_pk1(const Mat3& F, Mat3& P) const {
    P = pk1(F);
    return energy(F);
  }
  //! Bound on the largest eigenvalue of dP/dF for |sigma_i - 1| <= stretch = s. The second
  //! variation is dF : dF S + 2 mu |dE|^2 + lambda tr(dE)^2 with S = 2 mu E + lambda tr(E) I
  //! and dE = sym(F^T dF), so |dE| <= (1+s) |dF|, |E|_2 <= e = max((1+s)^2 - 1, 1 - (1-s)^2)/2
  //! and |S|_2 <= (2 mu + 3 |lambda|) e: together (2 mu + 3 |lambda|)((1+s)^2 + e).
  GEN4D_HD double projection_stiffness(double stretch = 0.1) const {
    const double a = 1.0 + stretch, b = 1.0 - stretch;
    const double e = 0.5 * ((a * a - 1.0) > (1.0 - b * b) ? (a * a - 1.0) : (1.0 - b * b));
    return (2.0 * mu + 3.0 * (lambda > 0 ? lambda : -lambda)) * (a * a + e);
  }
};

GEN4D_REGISTER_MATERIAL(StVK);

}  // namespace gen4d::materials
