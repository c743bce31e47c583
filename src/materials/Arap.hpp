//! As-rigid-as-possible elasticity psi = k/2 ||F - R||^2, pointwise and device-callable.
#pragma once

#include "materials/Hd.hpp"
#include "materials/Lame.hpp"
#include "materials/Mat3.hpp"
#include "materials/Registry.hpp"
#include "materials/Svd3.hpp"

namespace gen4d::materials {

//! ARAP: pure shape stiffness with no volume term; its projection target is p = R exactly.
struct Arap {
  static constexpr const char* name = "arap";
  double k;

  //! k = 2 mu, so that near rest psi ~ mu ||sym(F - I)||^2 matches the shear part of linear
  //! elasticity (ARAP has no separate bulk stiffness to match lambda); validates like Lame.
  static Arap from_young_poisson(double youngs_modulus, double poisson_ratio) {
    return Arap{2.0 * lame_from_young_poisson(youngs_modulus, poisson_ratio).mu};
  }

  //! k/2 sum (sigma_i - 1)^2 over the signed singular values, = k/2 ||F - R||^2.
  GEN4D_HD double energy_from_singular_values(const Vec3& s) const {
    const double d0 = s[0] - 1.0, d1 = s[1] - 1.0, d2 = s[2] - 1.0;
    return 0.5 * k * (d0 * d0 + d1 * d1 + d2 * d2);
  }
  GEN4D_HD double energy(const Mat3& F) const {
    Mat3 U, V;
    Vec3 s;
    svd3(F, U, s, V);
    return energy_from_singular_values(s);
  }

  GEN4D_HD Mat3 pk1(const Mat3& F, const Mat3& R) const { return k * (F - R); }
  GEN4D_HD Mat3 pk1(const Mat3& F) const { return pk1(F, polar_rotation(F)); }

  //! Energy and stress from one SVD (the solver's per-quadrature-point call).
  GEN4D_HD double energy_and_pk1(const Mat3& F, Mat3& P) const {
    Mat3 U, V;
    Vec3 s;
    svd3(F, U, s, V);
    P = pk1(F, U * transpose(V));
    return energy_from_singular_values(s);
  }

  //! dP/dF has eigenvalues k (stretch, twist) and k (1 - 2 / (sigma_i + sigma_j)) < k (flip)
  //! for every non-inverted F, so k itself bounds it and p = F - P/k = R is the ARAP target.
  GEN4D_HD double projection_stiffness() const { return k; }
};

GEN4D_REGISTER_MATERIAL(Arap);

}  // namespace gen4d::materials
