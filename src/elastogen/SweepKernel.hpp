//! Pointwise kernels of ElastoGen's global step (M/dt^2 + k L) delta = r, for host and device:
//! the 27-point interior stencil, the general row of a node with empty or
//! held neighbours, and one damped-Jacobi sweep as a per-value kernel (one GPU thread per
//! degree of freedom). The host's vectorised row loop and the GPU kernel share these
//! functions, so the arithmetic of a value is written once.
#pragma once

#include <cstdint>

#include "materials/Hd.hpp"

namespace gen4d::elastogen {

//! Interior coefficients: (m/dt^2 + k h c_centre), k h c_face, k h c_edge, k h c_corner.
struct StencilCoefficients {
  double centre, face, edge, corner;
};

//! Vectors live interleaved (3 values per node, x fastest) on the ghosted box, so value q's
//! neighbours along x, y, z are q -+ 3, q -+ Y, q -+ Z with Y = 3 gx, Z = 3 gx gy. The
//! stencil's 27 coefficients take one value per class (centre, 6 faces, 12 edges, 8 corners)
//! by the voxel's symmetry, so each class's neighbours are summed first: 23 adds and 4
//! multiplies per value. (A d)_q of an interior node (8 solid voxels of slot 0's density):
GEN4D_HD inline double interior_value(const StencilCoefficients& s, const double* d, long q, long Y,
                                      long Z) {
  const double faces = (d[q - 3] + d[q + 3]) + (d[q - Y] + d[q + Y]) + (d[q - Z] + d[q + Z]);
  const double edges = (d[q - Y - 3] + d[q - Y + 3] + d[q + Y - 3] + d[q + Y + 3]) +
                       (d[q - Z - 3] + d[q - Z + 3] + d[q + Z - 3] + d[q + Z + 3]) +
                       (d[q - Y - Z] + d[q + Y - Z] + d[q - Y + Z] + d[q + Y + Z]);
  const double corners =
      (d[q - Y - Z - 3] + d[q - Y - Z + 3] + d[q + Y - Z - 3] + d[q + Y - Z + 3]) +
      (d[q - Y + Z - 3] + d[q - Y + Z + 3] + d[q + Y + Z - 3] + d[q + Y + Z + 3]);
  return s.centre * d[q] + s.face * faces + s.edge * edges + s.corner * corners;
}

//! Interior coefficients of cells with unequal edges, one per neighbour class of a box's
//! reflection symmetry: (m/dt^2 + k c_centre) and k c times the Laplacian's coefficient of the
//! faces along x, y, z, the edges in the xy, xz, yz planes, and the corners.
struct AxisStencilCoefficients {
  double centre, fx, fy, fz, exy, exz, eyz, corner;
};

//! (A d)_q of an interior node for cells with unequal edges (interior_value's layout).
GEN4D_HD inline double interior_value_axes(const AxisStencilCoefficients& s, const double* d,
                                           long q, long Y, long Z) {
  const double fx = d[q - 3] + d[q + 3], fy = d[q - Y] + d[q + Y], fz = d[q - Z] + d[q + Z];
  const double exy = d[q - Y - 3] + d[q - Y + 3] + d[q + Y - 3] + d[q + Y + 3];
  const double exz = d[q - Z - 3] + d[q - Z + 3] + d[q + Z - 3] + d[q + Z + 3];
  const double eyz = d[q - Y - Z] + d[q + Y - Z] + d[q - Y + Z] + d[q + Y + Z];
  const double corners =
      (d[q - Y - Z - 3] + d[q - Y - Z + 3] + d[q + Y - Z - 3] + d[q + Y - Z + 3]) +
      (d[q - Y + Z - 3] + d[q - Y + Z + 3] + d[q + Y + Z - 3] + d[q + Y + Z + 3]);
  return s.centre * d[q] + s.fx * fx + s.fy * fy + s.fz * fz + s.exy * exy + s.exz * exz +
         s.eyz * eyz + s.corner * corners;
}

//! What the general row needs of the grid: each voxel's Laplacian K[l][m] times k (for cubes,
//! the unit-cube Laplacian times k h) and the ghosted linear offsets of a voxel's 8 corners from
//! its lowest corner.
struct GeneralStencil {
  double kK[8][8];
  long corner_offset[8];
  long gx, gxy;
};

//! Component `dof` of (A d) at a free node n with neighbour-voxel bits `adj` and lumped mass
//! term m_inv_dt2 = m / dt^2: the mass term plus k h K[l][m] d_m summed over its solid voxels.
GEN4D_HD inline double general_value(const GeneralStencil& g, const double* d, long n, unsigned adj,
                                     double m_inv_dt2, int dof) {
  double acc = m_inv_dt2 * d[3 * n + dof];
  for (int cell = 0; cell < 8; ++cell) {
    if (!(adj >> cell & 1u)) continue;
    const int a = cell & 1, b = (cell >> 1) & 1, c = (cell >> 2) & 1;
    const int l = 7 - cell;  // the node's corner in that voxel
    const long base = n - (1 - a) - (1 - b) * g.gx - (1 - c) * g.gxy;
    for (int m = 0; m < 8; ++m) acc += g.kK[l][m] * d[3 * (base + g.corner_offset[m]) + dof];
  }
  return acc;
}

//! One damped-Jacobi sweep, value by value over the owned box (3 per node, x fastest):
//! on free nodes rr = r - A d_old, d_new = d_old + rr omega / diag (and res = rr when res is
//! set); held and empty nodes copy d_old. d_old's ghosts must be current.
struct JacobiSweepKernel {
  const double* r;
  const double* diag;
  const double* mass;
  const std::uint8_t* free;
  const std::uint8_t* adj;
  const double* d_old;
  double* d_new;
  double* res;  //!< may be null
  StencilCoefficients s;
  AxisStencilCoefficients sa;  //!< used instead of s where `axes` is set
  bool axes = false;           //!< cells with unequal edges
  GeneralStencil g;
  double interior_mass, inv_dt2, omega;
  long o0, o1, o2, n0, n1, n2;  //!< owned box start (ghosted indices) and its counts
  long Y, Z;

  //! The kernel's index range: 3 values per owned node.
  GEN4D_HD long values() const { return 3 * n0 * n1 * n2; }

  GEN4D_HD void operator()(long t) const {
    const long node = t / 3;
    const int dof = static_cast<int>(t - 3 * node);
    const long i = node % n0, j = node / n0 % n1, k = node / (n0 * n1);
    const long n = (o0 + i) + (o1 + j) * g.gx + (o2 + k) * g.gxy;
    const long q = 3 * n + dof;
    if (!free[n]) {
      d_new[q] = d_old[q];
      return;
    }
    double v;
    if (adj[n] == 0xFFu && mass[n] == interior_mass) {
      v = axes ? interior_value_axes(sa, d_old, q, Y, Z) : interior_value(s, d_old, q, Y, Z);
    } else {
      v = general_value(g, d_old, n, adj[n], mass[n] * inv_dt2, dof);
    }
    const double rr = r[q] - v;
    if (res) res[q] = rr;
    d_new[q] = d_old[q] + rr * (omega / diag[n]);
  }
};

}  // namespace gen4d::elastogen
