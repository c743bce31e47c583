//! The J2 (von Mises) radial return in principal Hencky strain, shared by the MPM's
//! `von_mises` and `herschel_bulkley` models, its `drucker_prager` cone return, and the
//! `gen4d diagnose` voxel model's plasticity (forward/HenckyJ2.hpp).
//
// With e the principal Hencky strain and s = dev(tau) = 2 mu dev(e), the associative flow
// removes plastic strain along dev(e) / |dev e| and keeps tr(e): the return is radial.
#pragma once

#include <algorithm>
#include <cmath>

namespace gen4d::materials {

//! sqrt(2/3): the von Mises radius |s| of the uniaxial stress sigma_y is sqrt(2/3) sigma_y.
inline constexpr double kSqrt23 = 0.816496580927726032732428024902;

//! Von Mises equivalent of a (Kirchhoff) stress, sqrt(3/2 |dev tau|^2), row-major 3x3.
inline double mises(const double tau[9]) {
  const double p = (tau[0] + tau[4] + tau[8]) / 3.0;
  double s2 = 0;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) {
      const double d = tau[3 * a + b] - (a == b ? p : 0.0);
      s2 += d * d;
    }
  return std::sqrt(1.5 * s2);
}

//! Radial return of the principal strain e (any 3-vector with operator[]) by the plastic
//! multiplier dg: dev(e) <- dev(e) (1 - min(dg, n) / n) with eh = dev(e), n = |eh| > 0, tr(e)
//! unchanged.
template <class V3>
inline void radial_return(V3& e, const V3& eh, double n, double dg) {
  const double shrink = std::min(dg, n) / n;
  for (int k = 0; k < 3; ++k) e[k] -= shrink * eh[k];
}

//! Trial overstress f = 2 mu |dev e| - sqrt(2/3) (sigma_y + H eps_p) of linear isotropic
//! hardening; the point yields where f > 0.
inline double j2_linear_overstress(double dev_norm, double mu, double sigma_y, double H,
                                   double eps_p) {
  return 2 * mu * dev_norm - kSqrt23 * (sigma_y + H * eps_p);
}

//! Backward-Euler plastic multiplier of linear hardening, closed form: f / (2 mu + 2 H / 3);
//! the equivalent plastic strain grows by sqrt(2/3) times it.
inline double j2_linear_multiplier(double overstress, double mu, double H) {
  return overstress / (2 * mu + 2.0 / 3.0 * H);
}

}  // namespace gen4d::materials
