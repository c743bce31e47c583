//! The MPM substep's pointwise kernels: one source for the host (exec::parallel_for, see
//! Solver.cpp) and a GPU (exec::device_for, see Solver.cu).
//
// Each kernel acts on one particle or one grid node and sees only the raw arrays of its
// argument struct: no MPI, no containers, no strings (the boundary conditions arrive baked into
// GridCondition records). The grid is the rank's ghosted node box, x fastest, with 4 values per
// node for P2G (mass, momentum x, y, z; interleaved so one node is one 32-byte line segment) and
// 3 per node for the velocities.
//
// P2G adds integer multiples of a quantum (round_int below; see Solver.hpp): any order of the
// additions gives the same sums, so the host's slab colouring, a GPU's atomics and every rank
// count agree bit for bit.
#pragma once

#include <cmath>
#include <cstdint>

#include "materials/Hd.hpp"

namespace gen4d::mpm::kernels {

// Lanes of doubles worked on together. Quad: one node's (mass, momentum x, y, z) in P2G, a
// velocity and a spare lane in G2P. Pair: two neighbouring nodes of a row (8 contiguous grid
// values). On the host GCC vectors, so one AVX-512 instruction does a Pair and one AVX2
// instruction a Quad; on a GPU plain scalars. Lane by lane, each operation rounds as the scalar
// one would.
#if defined(__CUDACC__)
template <int N>
struct Lanes {
  double l[N];
  GEN4D_HD double operator[](int k) const { return l[k]; }
};
#define GEN4D_LANES_OP(op)                                                     \
  template <int N>                                                             \
  GEN4D_HD inline Lanes<N> operator op(const Lanes<N>& a, const Lanes<N>& b) { \
    Lanes<N> r;                                                                \
    for (int k = 0; k < N; ++k) r.l[k] = a.l[k] op b.l[k];                     \
    return r;                                                                  \
  }                                                                            \
  template <int N>                                                             \
  GEN4D_HD inline Lanes<N> operator op(const Lanes<N>& a, double s) {          \
    Lanes<N> r;                                                                \
    for (int k = 0; k < N; ++k) r.l[k] = a.l[k] op s;                          \
    return r;                                                                  \
  }
GEN4D_LANES_OP(+)
GEN4D_LANES_OP(-)
GEN4D_LANES_OP(*)
#undef GEN4D_LANES_OP
template <int N>
GEN4D_HD inline Lanes<N>& operator+=(Lanes<N>& a, const Lanes<N>& b) {
  return a = a + b;
}
using Quad = Lanes<4>;
using Pair = Lanes<8>;
GEN4D_HD inline Quad make_quad(double a, double b, double c, double d) {
  return {{a, b, c, d}};
}
GEN4D_HD inline Pair make_pair(const Quad& a, const Quad& b) {
  return {{a.l[0], a.l[1], a.l[2], a.l[3], b.l[0], b.l[1], b.l[2], b.l[3]}};
}
//! p[0..2] and a zero lane (reads three values).
GEN4D_HD inline Quad load_xyz(const double* p) {
  return {{p[0], p[1], p[2], 0.0}};
}
//! g[0..N) += q, plain (no other thread touches g).
template <int N>
GEN4D_HD inline void add_lanes(double* g, const Lanes<N>& q) {
  for (int k = 0; k < N; ++k) g[k] += q.l[k];
}
#else
// Passed by value only between inlined functions: no ABI to keep.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"
typedef double Quad __attribute__((vector_size(32)));
typedef double Pair __attribute__((vector_size(64)));
inline Quad make_quad(double a, double b, double c, double d) {
  return Quad{a, b, c, d};
}
inline Pair make_pair(const Quad& a, const Quad& b) {
  return __builtin_shufflevector(a, b, 0, 1, 2, 3, 4, 5, 6, 7);
}
//! p[0..2] in lanes 0-2; lane 3 holds p[3], which must be readable (arrays padded by one).
inline Quad load_xyz(const double* p) {
  Quad q;
  __builtin_memcpy(&q, p, sizeof q);
  return q;
}
//! g[0..lanes) += q, plain (no other thread touches g).
template <class V>
inline void add_lanes(double* g, const V& q) {
  V t;
  __builtin_memcpy(&t, g, sizeof t);
  t += q;
  __builtin_memcpy(g, &t, sizeof t);
}
#pragma GCC diagnostic pop
#endif

// Adding and subtracting 1.5 * 2^52 rounds a double of magnitude below 2^51 to the nearest
// integer (ties to even) in the default rounding mode; cheaper than std::nearbyint.
template <class T>
GEN4D_HD inline T round_int(T c) {
  const double k = 6755399441055744.0;
  return (c + k) - k;
}

GEN4D_HD inline double dot3(const double* a, const double* b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

//! Quadratic B-spline stencil of a particle: the first of its 3x3x3 nodes relative to the
//! ghosted box, the particle's offset from it in cells (fx in [0.5, 1.5)) and the weights.
struct Stencil {
  long base[3];
  double fx[3], w[3][3];

  GEN4D_HD Stencil(const double* xp, const double* lo, double dx, const long* start) {
    for (int a = 0; a < 3; ++a) {
      const double X = (xp[a] - lo[a]) / dx;
      const long b = static_cast<long>(std::floor(X - 0.5));
      const double f = X - static_cast<double>(b);
      fx[a] = f;
      w[a][0] = 0.5 * (1.5 - f) * (1.5 - f);
      w[a][1] = 0.75 - (f - 1.0) * (f - 1.0);
      w[a][2] = 0.5 * (f - 0.5) * (f - 0.5);
      base[a] = b - start[a];
    }
  }

  //! f(dy, dz, wzy, row) for the 9 rows of three nodes along x (z outer, y inner): the row's
  //! offsets from the particle (m), its y-z weight and the index of its first node in a box of
  //! gx x gy nodes.
  template <class F>
  GEN4D_HD void for_each_row(double dx, long gx, long gy, const F& f) const {
    for (int c = 0; c < 3; ++c) {
      const double dz = (c - fx[2]) * dx;
      for (int b = 0; b < 3; ++b) {
        const double dy = (b - fx[1]) * dx;
        f(dy, dz, w[2][c] * w[1][b], ((base[2] + c) * gy + (base[1] + b)) * gx + base[0]);
      }
    }
  }
};

//! The affine matrix P2G transfers: C blended towards its skew part by r (RPIC damping), or
//! zero for r < 0 (PIC).
GEN4D_HD inline void transfer_affine(const double* C, double r, double* out) {
  if (r == 0) {
    for (int k = 0; k < 9; ++k) out[k] = C[k];
    return;
  }
  if (r < 0) {
    for (int k = 0; k < 9; ++k) out[k] = 0.0;
    return;
  }
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b)
      out[3 * a + b] = (1 - r) * C[3 * a + b] + 0.5 * r * (C[3 * a + b] - C[3 * b + a]);
}

//! What P2G reads: the particles, the grid geometry and the quanta.
struct P2GArgs {
  const double *x, *v, *C, *tau, *mass, *vol0;
  const std::uint8_t* flag;
  double lo[3], dx, stress_scale, rpic;
  double inv_qm, inv_qp;  //!< inverse quanta of mass and momentum
  long start[3];          //!< ghosted box origin (global node index)
  long gx, gy;            //!< ghosted box size along x and y
};

//! max(a, b) for a not NaN: a NaN b is ignored, as std::fmax does (and it vectorises).
GEN4D_HD inline double max_of(double a, double b) {
  return b > a ? b : a;
}

//! Bound of particle i's largest P2G contribution, {mass, momentum}, for the quanta.
GEN4D_HD inline void p2g_bound(const P2GArgs& a, long i, double* bound) {
  const double m = a.mass[i];
  double mv = 0, s = 0, C[9];
  transfer_affine(&a.C[9 * i], a.rpic, C);
  for (int d = 0; d < 3; ++d) mv = max_of(mv, std::fabs(a.v[3 * i + d]));
  for (int k = 0; k < 9; ++k)
    s = max_of(s, std::fabs(a.stress_scale * a.vol0[i] * a.tau[9 * i + k]) + std::fabs(m * C[k]));
  bound[0] = m;
  bound[1] = m * mv + 3 * s * 1.5 * a.dx;
}

//! Scatters particle i into `grid` (4 values per node) through add(g, q), which adds the lanes
//! of q (a Quad: one node's mass, momentum x, y, z in quanta; a Pair: two neighbouring nodes)
//! to the grid values from g on: a plain addition where no other thread touches those nodes, an
//! atomic one otherwise.
template <class Add>
GEN4D_HD inline void p2g_particle(const P2GArgs& a, long i, double* grid, const Add& add) {
  if (a.flag[i] & 1) return;
  const Stencil st(&a.x[3 * i], a.lo, a.dx, a.start);
  const double dx = a.dx;
  const double m = a.mass[i];
  const double s = a.stress_scale * a.vol0[i];
  double A[9], C[9];
  transfer_affine(&a.C[9 * i], a.rpic, C);
  for (int k = 0; k < 9; ++k) A[k] = s * a.tau[9 * i + k] + m * C[k];
  // Lanes (mass, momentum x, y, z); the mass lane's affine terms are zero, so it stays m.
  const Quad mv = make_quad(m, m * a.v[3 * i], m * a.v[3 * i + 1], m * a.v[3 * i + 2]);
  const Quad ax = make_quad(0, A[0], A[3], A[6]), ay = make_quad(0, A[1], A[4], A[7]),
             az = make_quad(0, A[2], A[5], A[8]);
  const Quad inv_q = make_quad(a.inv_qm, a.inv_qp, a.inv_qp, a.inv_qp);
  double dxa[3];
  for (int o = 0; o < 3; ++o) dxa[o] = (o - st.fx[0]) * dx;
  // Nodes 0 and 1 of a row as one Pair (8 contiguous grid values), node 2 as a Quad.
  const auto both = [](double v) { return make_quad(v, v, v, v); };
  const Pair ax2 = make_pair(ax, ax), inv_q2 = make_pair(inv_q, inv_q);
  const Pair dxa01 = make_pair(both(dxa[0]), both(dxa[1]));
  const Pair w01 = make_pair(both(st.w[0][0]), both(st.w[0][1]));
  st.for_each_row(dx, a.gx, a.gy, [&](double dy, double dz, double wzy, long row) {
    // Affine momentum at the node: mv + A (dx0, dy, dz), weighted, rounded to its quantum.
    const Quad r = mv + ay * dy + az * dz;
    add(&grid[4 * row], round_int((make_pair(r, r) + ax2 * dxa01) * (w01 * wzy) * inv_q2));
    add(&grid[4 * (row + 2)], round_int((r + ax * dxa[2]) * (wzy * st.w[0][2]) * inv_q));
  });
}

//! A grid boundary condition of one substep (Solver bakes BoundaryConfig into these).
struct GridCondition {
  enum Kind : int { kCuboid, kSticky, kCut, kSeparate, kSlip, kReset };
  int kind;
  double lo[3], hi[3];  //!< cuboid's box at t, or the cut's region
  double velocity[3];   //!< cuboid
  double point[3], normal[3], friction, soft_width, cut_scale;
};

//! What the grid update reads.
struct GridArgs {
  const double* pm;  //!< 4 per node: mass, momentum (in quanta)
  double* vel;       //!< 3 per node, written
  double qm, qp;     //!< quanta
  double gravity[3], dt, damp, scale_v;
  double lo[3], dx;
  long start[3], count[3], nodes[3];
  int wall_layers;  //!< -1: the bounding-box walls are off
  const GridCondition* cond;
  int ncond;
};

GEN4D_HD inline bool in_box(const double* lo, const double* hi, const double* p) {
  for (int d = 0; d < 3; ++d)
    if (p[d] < lo[d] || p[d] > hi[d]) return false;
  return true;
}

//! Velocity of ghosted node n: momentum / mass + gravity, the scalings, then the conditions
//! in deck order and the bounding-box walls.
GEN4D_HD inline void grid_node(const GridArgs& a, long n) {
  double* v = &a.vel[3 * n];
  const double m = a.pm[4 * n] * a.qm;
  if (!(m > 0)) {
    v[0] = v[1] = v[2] = 0;
    return;
  }
  const double inv_m = a.qp / m;
  for (int d = 0; d < 3; ++d) v[d] = a.pm[4 * n + 1 + d] * inv_m + a.dt * a.gravity[d];
  if (a.scale_v != 1)
    for (int d = 0; d < 3; ++d) v[d] *= a.scale_v;
  if (a.damp != 1)
    for (int d = 0; d < 3; ++d) v[d] *= a.damp;
  const long i = n % a.count[0], j = (n / a.count[0]) % a.count[1],
             k = n / (a.count[0] * a.count[1]);
  const long idx[3] = {a.start[0] + i, a.start[1] + j, a.start[2] + k};
  const double xi[3] = {a.lo[0] + idx[0] * a.dx, a.lo[1] + idx[1] * a.dx, a.lo[2] + idx[2] * a.dx};
  for (int c = 0; c < a.ncond; ++c) {
    const GridCondition& bc = a.cond[c];
    if (bc.kind == GridCondition::kReset) {
      v[0] = v[1] = v[2] = 0;
      continue;
    }
    if (bc.kind == GridCondition::kCuboid) {
      if (in_box(bc.lo, bc.hi, xi))
        for (int d = 0; d < 3; ++d) v[d] = bc.velocity[d];
      continue;
    }
    const double* nrm = bc.normal;
    const double dist = (xi[0] - bc.point[0]) * nrm[0] + (xi[1] - bc.point[1]) * nrm[1] +
                        (xi[2] - bc.point[2]) * nrm[2];
    if (dist > 0 && !(dist < bc.soft_width)) continue;
    // Blend weight of a soft collider's outer band (1 on and inside the plane).
    const double wb = dist > 0 ? 1.0 - dist / bc.soft_width : 1.0;
    if (bc.kind == GridCondition::kSticky) {
      for (int d = 0; d < 3; ++d) v[d] -= wb * v[d];
      continue;
    }
    const double vn = dot3(v, nrm);
    if (bc.kind == GridCondition::kCut) {
      // Inside the cut: no normal velocity, cut_scale of the rest; elsewhere: stop.
      const bool in_cut = in_box(bc.lo, bc.hi, xi);
      for (int d = 0; d < 3; ++d) {
        const double target = in_cut ? bc.cut_scale * (v[d] - vn * nrm[d]) : 0.0;
        v[d] = wb == 1.0 ? target : v[d] + wb * (target - v[d]);
      }
      continue;
    }
    if (bc.kind == GridCondition::kSeparate && vn >= 0) continue;
    double vt[3];
    for (int d = 0; d < 3; ++d) vt[d] = v[d] - vn * nrm[d];
    const double vtn = std::sqrt(dot3(vt, vt));
    // Coulomb: the tangential speed drops by friction times the normal speed removed.
    const double scale = vtn > 0 ? std::fmax(0.0, 1.0 - bc.friction * std::fabs(vn) / vtn) : 0.0;
    if (wb == 1.0)
      for (int d = 0; d < 3; ++d) v[d] = vt[d] * scale;
    else
      for (int d = 0; d < 3; ++d) v[d] += wb * (vt[d] * scale - v[d]);
  }
  if (a.wall_layers >= 0) {
    const long L = a.wall_layers;
    for (int d = 0; d < 3; ++d) {
      if (idx[d] < L && v[d] < 0) v[d] = 0;
      if (idx[d] > a.nodes[d] - 1 - L && v[d] > 0) v[d] = 0;
    }
  }
}

//! F <- (I + dt C) F for row-major 3x3 C and F: the MLS-MPM update of a deformation gradient by
//! the velocity gradient of one substep (one order of operations for every F it updates).
GEN4D_HD inline void advance_deformation(const double* C, double dt, double* F) {
  double G[9];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      G[3 * r + c] = F[3 * r + c] +
                     dt * (C[3 * r + 0] * F[c] + C[3 * r + 1] * F[3 + c] + C[3 * r + 2] * F[6 + c]);
  for (int k = 0; k < 9; ++k) F[k] = G[k];
}

//! What G2P reads and writes.
struct G2PArgs {
  double *x, *v, *C, *F;
  const std::uint8_t* flag;
  const double* vel;  //!< 3 per ghosted node, and one spare double at the end (see load_xyz)
  double lo[3], dx, dt;
  long start[3], gx, gy;
  bool advance;  //!< also move x and F (false when particle conditions act in between)
};

//! Particle i's velocity and affine matrix from the grid; with `advance`, also x and F.
GEN4D_HD inline void g2p_particle(const G2PArgs& a, long i) {
  if (a.flag[i] & 1) return;
  const double dx = a.dx, inv_dx = 1.0 / dx;
  const Stencil st(&a.x[3 * i], a.lo, dx, a.start);
  // Lanes x, y, z (the fourth idles): the velocity and B's columns (dx, dy, dz) summed node by
  // node in the stencil's order.
  Quad vn = make_quad(0, 0, 0, 0), b0 = vn, b1 = vn, b2 = vn;
  double dxa[3];
  for (int o = 0; o < 3; ++o) dxa[o] = (o - st.fx[0]) * dx;
  st.for_each_row(dx, a.gx, a.gy, [&](double dy, double dz, double wzy, long row) {
    for (int o = 0; o < 3; ++o) {
      const Quad wv = load_xyz(&a.vel[3 * (row + o)]) * (wzy * st.w[0][o]);
      vn += wv;
      b0 += wv * dxa[o];
      b1 += wv * dy;
      b2 += wv * dz;
    }
  });
  const double cs = 4.0 * inv_dx * inv_dx;
  double* C = &a.C[9 * i];
  for (int d = 0; d < 3; ++d) {
    C[3 * d] = cs * b0[d];
    C[3 * d + 1] = cs * b1[d];
    C[3 * d + 2] = cs * b2[d];
    a.v[3 * i + d] = vn[d];
  }
  if (!a.advance) return;
  for (int d = 0; d < 3; ++d) a.x[3 * i + d] += a.dt * vn[d];
  advance_deformation(C, a.dt, &a.F[9 * i]);
}

//! What the guard reads and writes.
struct GuardArgs {
  double *x, *v;
  const double* F;
  double lo[3], dx, dt, limit;
  long nodes[3];
  bool remove_outside;
};

enum GuardStatus : std::uint8_t { kInside = 0, kUnstable = 1, kRemove = 2, kClamped = 3 };

//! Particle i after its move: unstable (non-finite or faster than `limit` per substep), outside
//! the grid's interior (then removed, or clamped back with its outward velocity dropped), or fine.
GEN4D_HD inline std::uint8_t guard_particle(const GuardArgs& a, long i) {
  double* x = &a.x[3 * i];
  double* v = &a.v[3 * i];
  bool finite = true;
  for (int d = 0; d < 3; ++d) finite &= std::isfinite(x[d]) && std::isfinite(v[d]);
  for (int k = 0; k < 9; ++k) finite &= std::isfinite(a.F[9 * i + k]);
  const double speed = std::sqrt(dot3(v, v));
  if (!finite || speed * a.dt > a.limit) return kUnstable;
  bool outside = false;
  for (int d = 0; d < 3; ++d) {
    const double X = (x[d] - a.lo[d]) / a.dx;
    const double hi = static_cast<double>(a.nodes[d] - 2);
    if (X < 1.0 || X >= hi) outside = true;
  }
  if (!outside) return kInside;
  if (a.remove_outside) return kRemove;
  for (int d = 0; d < 3; ++d) {
    const double X = (x[d] - a.lo[d]) / a.dx;
    const double hi = static_cast<double>(a.nodes[d] - 2) - 1e-6;
    if (X < 1.0) {
      x[d] = a.lo[d] + a.dx;
      v[d] = std::fmax(v[d], 0.0);
    } else if (X >= hi) {
      x[d] = a.lo[d] + hi * a.dx;
      v[d] = std::fmin(v[d], 0.0);
    }
  }
  return kClamped;
}

}  // namespace gen4d::mpm::kernels
