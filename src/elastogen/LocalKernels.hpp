//! Pointwise kernels of ElastoGen's local step, for host and device: the voxel's eight
//! Gauss-point deformation gradients and their transposed node forces in factored form, and
//! the fixed corotated and ARAP stresses from a Newton polar decomposition instead of a
//! Jacobi SVD.
#pragma once

#include <cmath>

#include "materials/Arap.hpp"
#include "materials/FixedCorotated.hpp"
#include "materials/Hd.hpp"
#include "materials/Mat3.hpp"
#include "materials/Svd3.hpp"

namespace gen4d::elastogen {

//! The trilinear voxel's 2x2x2 Gauss rule in factored form. Along axis b, dN_l/dxi_b at Gauss
//! point q is +-w(l_1, q_1) w(l_2, q_2) over the two other axes, with w = gp where the corner
//! and point bits agree and gm where they differ. So column b of every F_q is a bilinear
//! blend of the voxel's four edge vectors along b (it does not depend on q_b), and the
//! transposed convolution is the same blend applied to the column sums over q_b: 12 edge
//! differences and two 2x2 blends per axis instead of 8 x 8 x 9 multiply-adds per voxel.
struct HexGauss {
  static constexpr double kGp = 0.78867513459481288225;  //!< 0.5 + 0.5 / sqrt(3)
  static constexpr double kGm = 0.21132486540518711775;  //!< 0.5 - 0.5 / sqrt(3)

  //! The other two axes of axis b, ascending.
  GEN4D_HD static void others(int b, int& o1, int& o2) {
    o1 = b == 0 ? 1 : 0;
    o2 = b == 2 ? 1 : 2;
  }

  //! out[u][v] = sum_{s,t} w(s, u) w(t, v) in[s][t] (3 components): symmetric in (s,t) <->
  //! (u,v), so it maps edge vectors to Gauss points and Gauss-point sums back to edges.
  GEN4D_HD static void blend(const double in[2][2][3], double wp, double wm, double out[2][2][3]) {
    double mid[2][2][3];
    for (int u = 0; u < 2; ++u)
      for (int t = 0; t < 2; ++t)
        for (int a = 0; a < 3; ++a) mid[u][t][a] = kGp * in[u][t][a] + kGm * in[1 - u][t][a];
    for (int u = 0; u < 2; ++u)
      for (int v = 0; v < 2; ++v)
        for (int a = 0; a < 3; ++a) out[u][v][a] = wp * mid[u][v][a] + wm * mid[u][1 - v][a];
  }

  //! F_q (row-major 3x3) at the eight Gauss points q = q0 + 2 q1 + 4 q2 from the corner
  //! positions xe[l][3] (corner l = a + 2b + 4c at local (a, b, c)) of a cube of edge 1/inv_h.
  GEN4D_HD static void gradients(const double xe[8][3], double inv_h, double F[8][9]) {
    const double inv[3] = {inv_h, inv_h, inv_h};
    gradients(xe, inv, F);
  }

  //! The same for a cell of edges 1/inv_h[b] along axis b (column b of F scales by inv_h[b]).
  GEN4D_HD static void gradients(const double xe[8][3], const double inv_h[3], double F[8][9]) {
    for (int b = 0; b < 3; ++b) {
      int o1, o2;
      others(b, o1, o2);
      double edge[2][2][3], col[2][2][3];
      for (int s = 0; s < 2; ++s)
        for (int t = 0; t < 2; ++t) {
          const int l0 = s << o1 | t << o2, l1 = l0 | 1 << b;
          for (int a = 0; a < 3; ++a) edge[s][t][a] = xe[l1][a] - xe[l0][a];
        }
      blend(edge, kGp * inv_h[b], kGm * inv_h[b], col);
      for (int q = 0; q < 8; ++q) {
        const double* c = col[q >> o1 & 1][q >> o2 & 1];
        for (int a = 0; a < 3; ++a) F[q][3 * a + b] = c[a];
      }
    }
  }

  //! Node forces fe[l][3] = scale * sum_q P_q grad N_l(q) (overwritten, not accumulated), the
  //! transposed convolution of gradients(); scale = quadrature weight / h.
  GEN4D_HD static void forces(const double P[8][9], double scale, double fe[8][3]) {
    const double sc[3] = {scale, scale, scale};
    forces(P, sc, fe);
  }

  //! The same for a cell of unequal edges: scale[b] = quadrature weight / h_b.
  GEN4D_HD static void forces(const double P[8][9], const double scale[3], double fe[8][3]) {
    for (int l = 0; l < 8; ++l)
      for (int a = 0; a < 3; ++a) fe[l][a] = 0.0;
    for (int b = 0; b < 3; ++b) {
      int o1, o2;
      others(b, o1, o2);
      double sum[2][2][3], edge[2][2][3];
      for (int u = 0; u < 2; ++u)
        for (int v = 0; v < 2; ++v) {
          const int q0 = u << o1 | v << o2, q1 = q0 | 1 << b;
          for (int a = 0; a < 3; ++a) sum[u][v][a] = P[q0][3 * a + b] + P[q1][3 * a + b];
        }
      blend(sum, kGp * scale[b], kGm * scale[b], edge);
      for (int s = 0; s < 2; ++s)
        for (int t = 0; t < 2; ++t) {
          const int l0 = s << o1 | t << o2, l1 = l0 | 1 << b;
          for (int a = 0; a < 3; ++a) {
            fe[l1][a] += edge[s][t][a];
            fe[l0][a] -= edge[s][t][a];
          }
        }
    }
  }
};

//! Rotation R of F = R S by Newton's polar iteration X <- (X + X^-T) / 2 from X = F (cof F and
//! det F given, as the stress needs them too). Unscaled: the iterates keep F's rotation and
//! their stretch converges quadratically to I, in 2-3 steps for the strains of an elastic
//! solid (|S - I| ~ 1e-3), so no scaling is needed there. Stops when a step moves X by
//! <= 1e-8 (its error is then ~ the square of that, below rounding); agrees with the signed
//! SVD's U V^T to ~1e-15. Returns false, R untouched, where det F <= 0 (the signed SVD then
//! gives the proper rotation) or after 16 steps (very large stretch).
GEN4D_HD inline bool polar_rotation_near(const materials::Mat3& F, const materials::Mat3& cofF,
                                         double J, materials::Mat3& R) {
  if (!(J > 0.0)) return false;
  materials::Mat3 X = F, C = cofF;
  double d = J;
  for (int it = 0; it < 16; ++it) {
    const double c = 0.5 / d;
    double change = 0.0;
    for (int a = 0; a < 9; ++a) {
      const double xn = 0.5 * X.a[a] + c * C.a[a];
      const double e = xn - X.a[a];
      change += e * e;
      X.a[a] = xn;
    }
    if (change <= 1e-16) {
      R = X;
      return true;
    }
    C = materials::cofactor(X);
    d = materials::det(X);
    if (!(d > 0.0)) return false;
  }
  return false;
}

//! Fixed corotated stress and energy density through polar_rotation_near (one cofactor and
//! 2-3 Newton steps instead of five Jacobi sweeps and a QR), falling back to the law's
//! signed-SVD path for inverted or extremely stretched points. Same formulas as
//! FixedCorotated: P = 2 mu (F - R) + lambda (J - 1) cof F, psi = mu |F - R|^2 +
//! lambda/2 (J - 1)^2 (= mu sum (sigma_i - 1)^2 + ... for det F > 0).
struct CorotatedPolarStress {
  materials::FixedCorotated law;
  GEN4D_HD double operator()(const double* F, double* P) const {
    materials::Mat3 Fm;
    for (int a = 0; a < 9; ++a) Fm.a[a] = F[a];
    const materials::Mat3 C = materials::cofactor(Fm);
    const double J = materials::det(Fm);
    materials::Mat3 R;
    if (!polar_rotation_near(Fm, C, J, R)) {
      materials::Mat3 Pm;
      const double psi = law.energy_and_pk1(Fm, Pm);
      for (int a = 0; a < 9; ++a) P[a] = Pm.a[a];
      return psi;
    }
    const double tm = 2.0 * law.mu, tl = law.lambda * (J - 1.0);
    double dev = 0.0;
    for (int a = 0; a < 9; ++a) {
      const double e = Fm.a[a] - R.a[a];
      dev += e * e;
      P[a] = tm * e + tl * C.a[a];
    }
    return law.mu * dev + 0.5 * law.lambda * (J - 1.0) * (J - 1.0);
  }
};

//! ARAP's stress and energy density (P = k (F - R), psi = k/2 |F - R|^2) through
//! polar_rotation_near, with the law's signed-SVD path as the fallback.
struct ArapPolarStress {
  materials::Arap law;
  GEN4D_HD double operator()(const double* F, double* P) const {
    materials::Mat3 Fm;
    for (int a = 0; a < 9; ++a) Fm.a[a] = F[a];
    materials::Mat3 R;
    if (!polar_rotation_near(Fm, materials::cofactor(Fm), materials::det(Fm), R)) {
      materials::Mat3 Pm;
      const double psi = law.energy_and_pk1(Fm, Pm);
      for (int a = 0; a < 9; ++a) P[a] = Pm.a[a];
      return psi;
    }
    double dev = 0.0;
    for (int a = 0; a < 9; ++a) {
      const double e = Fm.a[a] - R.a[a];
      dev += e * e;
      P[a] = law.k * e;
    }
    return 0.5 * law.k * dev;
  }
};

}  // namespace gen4d::elastogen
