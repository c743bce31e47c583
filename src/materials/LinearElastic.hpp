//! Small-strain linear elasticity, pointwise and device-callable.
#pragma once

#include "materials/Hd.hpp"
#include "materials/Lame.hpp"
#include "materials/Mat3.hpp"
#include "materials/Registry.hpp"

namespace gen4d::materials {

//! psi = mu ||eps||^2 + lambda/2 tr(eps)^2, eps = sym(F) - I. Quadratic, so dP/dF is the
//! constant isotropic tensor; not rotation invariant (large rotations create stress).
struct LinearElastic : LameLaw<LinearElastic> {
  static constexpr const char* name = "linear";
  GEN4D_HD static Mat3 small_strain(const Mat3& F) {
    return 0.5 * (F + transpose(F)) - identity3();
  }
  GEN4D_HD double energy(const Mat3& F) const {
    return quadratic_strain_energy(small_strain(F), mu, lambda);
  }
  GEN4D_HD Mat3 pk1(const Mat3& F) const {
    return quadratic_strain_stress(small_strain(F), mu, lambda);
  }
  GEN4D_HD double energy_and_pk1(const Mat3& F, Mat3& P) const {
    P = pk1(F);
    return energy(F);
  }
  //! The exact largest eigenvalue of dP/dF (dilation): 2 mu + 3 lambda (lambda >= 0), 2 mu
  //! otherwise.
  GEN4D_HD double projection_stiffness() const {
    return 2.0 * mu + (lambda > 0 ? 3.0 * lambda : 0.0);
  }
};

GEN4D_REGISTER_MATERIAL(LinearElastic);

}  // namespace gen4d::materials
