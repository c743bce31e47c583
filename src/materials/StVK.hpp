//! Saint Venant-Kirchhoff elasticity, pointwise and device-callable.
#pragma once

#include "materials/Hd.hpp"
#include "materials/Lame.hpp"
#include "materials/Mat3.hpp"
#include "materials/Registry.hpp"
#include "materials/Svd3.hpp"

namespace gen4d::materials {

//! psi = mu ||E||^2 + lambda/2 tr(E)^2 with the Green strain E = (F^T F - I)/2. Exact for
//! large rotations, but it softens under strong compression (it is not inversion-safe).
struct StVK : LameLaw<StVK> {
  static constexpr const char* name = "stvk";
  GEN4D_HD static Mat3 green_strain(const Mat3& F) {
    return 0.5 * (transpose(F) * F - identity3());
  }
  GEN4D_HD double energy(const Mat3& F) const {
    return quadratic_strain_energy(green_strain(F), mu, lambda);
  }
  //! P = F (2 mu E + lambda tr(E) I).
  GEN4D_HD Mat3 pk1(const Mat3& F) const {
    return F * quadratic_strain_stress(green_strain(F), mu, lambda);
  }
  GEN4D_HD double energy_and_pk1(const Mat3& F, Mat3& P) const {
    P = pk1(F);
    return energy(F);
  }
  //! Whether det F > 0 and every principal stretch of F exceeds sc (0 < sc < 1), without an
  //! SVD: the eigenvalues of C = F^T F all exceed s = sc^2 exactly when the characteristic
  //! polynomial p(x) = x^3 - I1 x^2 + I2 x - I3 and its derivatives alternate in sign at s
  //! (p < 0, p' > 0, p'' < 0: Budan-Fourier, exact for a polynomial with real roots).
  //! Conservative at rounding level; F row-major, entries a[3 r + c].
  GEN4D_HD static bool stretches_above(const double* F, double sc) {
    double C[9];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c)
        C[3 * r + c] = F[r] * F[c] + F[3 + r] * F[3 + c] + F[6 + r] * F[6 + c];
    const double J = F[0] * (F[4] * F[8] - F[5] * F[7]) - F[1] * (F[3] * F[8] - F[5] * F[6]) +
                     F[2] * (F[3] * F[7] - F[4] * F[6]);
    const double i1 = C[0] + C[4] + C[8];
    const double i2 =
        (C[0] * C[4] + C[0] * C[8] + C[4] * C[8]) - (C[1] * C[1] + C[2] * C[2] + C[5] * C[5]);
    const double s = sc * sc;
    return J > 0 && i1 > 3.0 * s && (3.0 * s * s - 2.0 * i1 * s + i2) > 0 &&
           ((s - i1) * s + i2) * s - J * J < 0;
  }
  //! StVK continued below the principal stretch sc (Irving, Teran, Fedkiw 2004, "Invertible
  //! finite elements"): with the signed SVD F = U diag(sigma) V^T and sigma* = max(sigma, sc),
  //! the principal stress P^_i(sigma) = sigma_i (mu (sigma_i^2 - 1) + lambda/2 sum_k
  //! (sigma_k^2 - 1)) is replaced by its first-order expansion about sigma*, and
  //! P = U diag(P^) V^T. Where every stretch is at least sc this is StVK's stress; below, the
  //! stress keeps the slope StVK has at sc instead of softening towards its compressive limit
  //! point (sigma = 1/sqrt 3 uniaxially) and its zero-energy reflections (C = I, det F = -1),
  //! so an element squeezed flat or turned inside out is pushed back. Returns false (P
  //! untouched) where every stretch is at least sc.
  GEN4D_HD bool pk1_continued(const Mat3& F, double sc, Mat3& P) const {
    Mat3 U, V;
    Vec3 sg;
    svd3(F, U, sg, V);
    if (sg.v[2] >= sc) return false;  // sorted: sigma_2 is the smallest (and signed)
    double st[3], sum = 0;
    for (int i = 0; i < 3; ++i) st[i] = sg.v[i] > sc ? sg.v[i] : sc, sum += st[i] * st[i] - 1.0;
    double ph[3];
    for (int i = 0; i < 3; ++i) {
      const double diag = mu * (st[i] * st[i] - 1.0) + 0.5 * lambda * sum;
      ph[i] = st[i] * diag;
      for (int j = 0; j < 3; ++j) {
        const double dij =
            lambda * st[i] * st[j] + (i == j ? diag + 2.0 * mu * st[i] * st[i] : 0.0);
        ph[i] += dij * (sg.v[j] - st[j]);
      }
    }
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c)
        P.a[3 * r + c] = U.a[3 * r] * ph[0] * V.a[3 * c] + U.a[3 * r + 1] * ph[1] * V.a[3 * c + 1] +
                         U.a[3 * r + 2] * ph[2] * V.a[3 * c + 2];
    return true;
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
