//! Lame parameters from Young's modulus and Poisson's ratio, with deck-value validation.
#pragma once

#include <cmath>
#include <string>

#include <fmt/format.h>

#include "core/Error.hpp"

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

}  // namespace gen4d::materials
