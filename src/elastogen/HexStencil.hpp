//! The trilinear voxel's 2x2x2 Gauss-point stencil: deformation gradients (the convolution
//! of seed Eq. 8), its transpose (node forces), and the element Laplacian used by the
//! projective-dynamics global matrix.
#pragma once

#include <array>
#include <cmath>

namespace gen4d::elastogen {

//! Corner l = a + 2b + 4c sits at local (a, b, c) in {0,1}^3; Gauss point q likewise at
//! 0.5 -/+ 0.5/sqrt(3) per axis. Full 2x2x2 integration has no hourglass modes, unlike the
//! one-point rule whose checkerboard displacement has zero energy.
struct HexStencil {
  //! dN_l/dxi at Gauss point q (unit cube), [q][l][axis].
  double dN[8][8][3];
  //! Unit-cube Laplacian stiffness K[l][m] = sum_q 1/8 dN_l(q) . dN_m(q).
  double K[8][8];
  //! Its part along each axis, Kd[d][l][m] = sum_q 1/8 dN_l,d(q) dN_m,d(q): a cell of edges
  //! h_d has the Laplacian hx hy hz sum_d Kd[d] / h_d^2.
  double Kd[3][8][8];

  static const HexStencil& get() {
    static const HexStencil s;
    return s;
  }

 private:
  HexStencil() {
    const double g[2] = {0.5 - 0.5 / std::sqrt(3.0), 0.5 + 0.5 / std::sqrt(3.0)};
    for (int q = 0; q < 8; ++q) {
      const double xi[3] = {g[q & 1], g[(q >> 1) & 1], g[(q >> 2) & 1]};
      for (int l = 0; l < 8; ++l) {
        const int c[3] = {l & 1, (l >> 1) & 1, (l >> 2) & 1};
        double n1[3], d1[3];
        for (int d = 0; d < 3; ++d) {
          n1[d] = c[d] ? xi[d] : 1.0 - xi[d];
          d1[d] = c[d] ? 1.0 : -1.0;
        }
        dN[q][l][0] = d1[0] * n1[1] * n1[2];
        dN[q][l][1] = n1[0] * d1[1] * n1[2];
        dN[q][l][2] = n1[0] * n1[1] * d1[2];
      }
    }
    for (int l = 0; l < 8; ++l)
      for (int m = 0; m < 8; ++m) {
        double s = 0;
        for (int q = 0; q < 8; ++q)
          for (int d = 0; d < 3; ++d) s += 0.125 * dN[q][l][d] * dN[q][m][d];
        K[l][m] = s;
        for (int d = 0; d < 3; ++d) {
          double sd = 0;
          for (int q = 0; q < 8; ++q) sd += 0.125 * dN[q][l][d] * dN[q][m][d];
          Kd[d][l][m] = sd;
        }
      }
  }
};

//! F_q = sum_l x_l (x) grad N_l(q), row-major 3x3, from the 8 corner positions xe[l][3].
inline void deformation_gradient(const HexStencil& s, int q, const double xe[8][3], double inv_h,
                                 double F[9]) {
  for (int a = 0; a < 9; ++a) F[a] = 0.0;
  for (int l = 0; l < 8; ++l)
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) F[3 * a + b] += xe[l][a] * s.dN[q][l][b] * inv_h;
}

//! The same for a cell of edges 1/inv_h[b] along axis b.
inline void deformation_gradient(const HexStencil& s, int q, const double xe[8][3],
                                 const double inv_h[3], double F[9]) {
  for (int a = 0; a < 9; ++a) F[a] = 0.0;
  for (int l = 0; l < 8; ++l)
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) F[3 * a + b] += xe[l][a] * s.dN[q][l][b] * inv_h[b];
}

//! Transposed convolution: adds w * P grad N_l(q) to the corner forces fe[l][3].
inline void add_node_forces(const HexStencil& s, int q, const double P[9], double w_inv_h,
                            double fe[8][3]) {
  for (int l = 0; l < 8; ++l)
    for (int a = 0; a < 3; ++a)
      fe[l][a] += w_inv_h * (P[3 * a] * s.dN[q][l][0] + P[3 * a + 1] * s.dN[q][l][1] +
                             P[3 * a + 2] * s.dN[q][l][2]);
}

}  // namespace gen4d::elastogen
