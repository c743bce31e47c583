//! Lame parameters from Young's modulus and Poisson's ratio, with deck-value validation.
#pragma once

#include <cmath>
#include <string>

#include <fmt/format.h>

#include "core/Error.hpp"
#include "materials/Hd.hpp"
#include "materials/Mat3.hpp"

namespace gen4d::materials {

struct Lame {
  double mu;      //!< shear modulus, Pa
  double lambda;  //!< first Lame parameter, Pa
};

//! mu = E / (2 (1 + nu)), lambda = E nu / ((1 + nu)(1 - 2 nu)). Throws InputError naming the
//! [material] key when E <= 0 or nu is outside (-1, 0.5), where the moduli stop being positive.
inline Lame lame_from_young_poisson(double youngs_modulus, double poisson_ratio) {
  if (!(youngs_modulus > 0.0) || !std::isfinite(youngs_modulus))
    throw InputError(fmt::format("[material] youngs_modulus must be a finite value > 0, got {}",
                                 youngs_modulus));
  if (!(poisson_ratio > -1.0 && poisson_ratio < 0.5))
    throw InputError(
        fmt::format("[material] poisson_ratio must be in (-1, 0.5), got {}", poisson_ratio));
  const double E = youngs_modulus, nu = poisson_ratio;
  return Lame{E / (2.0 * (1.0 + nu)), E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))};
}

//! Base of a law whose parameters are the Lame pair itself (CRTP: Law derives from
//! LameLaw<Law> and stays an aggregate, Law{mu, lambda}).
template <class Law>
struct LameLaw {
  double mu;      //!< shear modulus, Pa
  double lambda;  //!< first Lame parameter, Pa

  //! The law at the deck's (E, nu); InputError on E <= 0 or nu outside (-1, 0.5).
  static Law from_young_poisson(double youngs_modulus, double poisson_ratio) {
    const Lame l = lame_from_young_poisson(youngs_modulus, poisson_ratio);
    return Law{l.mu, l.lambda};
  }
};

//! The isotropic quadratic energy mu ||e||^2 + lambda/2 tr(e)^2 of a symmetric strain e.
GEN4D_HD inline double quadratic_strain_energy(const Mat3& e, double mu, double lambda) {
  const double tr = e.a[0] + e.a[4] + e.a[8];
  return mu * frobenius_dot(e, e) + 0.5 * lambda * tr * tr;
}

//! Its derivative with respect to e: 2 mu e + lambda tr(e) I.
GEN4D_HD inline Mat3 quadratic_strain_stress(const Mat3& e, double mu, double lambda) {
  const double tr = e.a[0] + e.a[4] + e.a[8];
  return 2.0 * mu * e + (lambda * tr) * identity3();
}

}  // namespace gen4d::materials
