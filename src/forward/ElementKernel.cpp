// Built with -ffp-contract=off (src/CMakeLists.txt): a fused multiply-add would round once
// where the scalar loop rounds twice, and the builds would differ in their last bits.
#include "forward/ElementKernel.hpp"

#include "forward/Isa.hpp"
#include "materials/StVK.hpp"
#include "materials/Svd3.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace gen4d::forward {

namespace {

constexpr int kLanes = 8;      // Gauss points per voxel
constexpr int kShapePad = 12;  // shapes rounded up to whole 4-lane vectors
using Lanes = double[kLanes];

// F[3a + c][q] = sum_l x[l][a] G[l][c][q], summed over l in order.
GEN4D_ALWAYS_INLINE void lanes_grad(const double (*G)[3][kLanes], const double x[kShapes][3],
                                    Lanes F[9]) {
  for (int i = 0; i < 9; ++i)
    for (int q = 0; q < kLanes; ++q) F[i][q] = 0;
  for (int l = 0; l < kShapes; ++l)
    for (int a = 0; a < 3; ++a) {
      const double xa = x[l][a];
      for (int c = 0; c < 3; ++c)
        for (int q = 0; q < kLanes; ++q) F[3 * a + c][q] += xa * G[l][c][q];
    }
}

// Cofactor and determinant of each lane's matrix, in the order of materials::cofactor, det.
GEN4D_ALWAYS_INLINE void lanes_cofactor(const Lanes A[9], Lanes C[9]) {
  for (int q = 0; q < kLanes; ++q) {
    C[0][q] = A[4][q] * A[8][q] - A[5][q] * A[7][q];
    C[1][q] = A[5][q] * A[6][q] - A[3][q] * A[8][q];
    C[2][q] = A[3][q] * A[7][q] - A[4][q] * A[6][q];
    C[3][q] = A[2][q] * A[7][q] - A[1][q] * A[8][q];
    C[4][q] = A[0][q] * A[8][q] - A[2][q] * A[6][q];
    C[5][q] = A[1][q] * A[6][q] - A[0][q] * A[7][q];
    C[6][q] = A[1][q] * A[5][q] - A[2][q] * A[4][q];
    C[7][q] = A[2][q] * A[3][q] - A[0][q] * A[5][q];
    C[8][q] = A[0][q] * A[4][q] - A[1][q] * A[3][q];
  }
}
GEN4D_ALWAYS_INLINE void lanes_det(const Lanes A[9], Lanes d) {
  for (int q = 0; q < kLanes; ++q)
    d[q] = A[0][q] * (A[4][q] * A[8][q] - A[5][q] * A[7][q]) -
           A[1][q] * (A[3][q] * A[8][q] - A[5][q] * A[6][q]) +
           A[2][q] * (A[3][q] * A[7][q] - A[4][q] * A[6][q]);
}
// StVK: E = (F^T F - I) / 2, S = 2 mu E + lambda tr(E) I, P = F S (m2 = 2 mu), in the order
// of materials::StVK::pk1.
// continued: when set, counts the lanes below the continued stretch (or inverted).
GEN4D_ALWAYS_INLINE void lanes_stvk(const Lanes F[9], double m2, double lambda, Lanes P[9],
                                    long* continued = nullptr) {
  alignas(64) Lanes E[9], tr;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      const double id = r == c ? 1.0 : 0.0;
      for (int q = 0; q < kLanes; ++q)
        E[3 * r + c][q] =
            0.5 * (F[r][q] * F[c][q] + F[3 + r][q] * F[3 + c][q] + F[6 + r][q] * F[6 + c][q] - id);
    }
  for (int q = 0; q < kLanes; ++q) tr[q] = lambda * (E[0][q] + E[4][q] + E[8][q]);
  for (int i = 0; i < 9; ++i) {
    const double id = i % 4 == 0 ? 1.0 : 0.0;
    for (int q = 0; q < kLanes; ++q) E[i][q] = m2 * E[i][q] + tr[q] * id;  // now S
  }
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      for (int q = 0; q < kLanes; ++q)
        P[3 * r + c][q] =
            F[3 * r][q] * E[c][q] + F[3 * r + 1][q] * E[3 + c][q] + F[3 * r + 2][q] * E[6 + c][q];
  // Below the continued stretch (or inverted), the scalar loop's continuation, lane by lane;
  // the screen is materials::StVK::stretches_above in lanes, operation for operation.
  constexpr double sc = kStvkContinuedStretch, s = sc * sc;
  alignas(64) Lanes C[9], J, i1, i2;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      for (int q = 0; q < kLanes; ++q)
        C[3 * r + c][q] = F[r][q] * F[c][q] + F[3 + r][q] * F[3 + c][q] + F[6 + r][q] * F[6 + c][q];
  lanes_det(F, J);
  for (int q = 0; q < kLanes; ++q) {
    i1[q] = C[0][q] + C[4][q] + C[8][q];
    i2[q] = (C[0][q] * C[4][q] + C[0][q] * C[8][q] + C[4][q] * C[8][q]) -
            (C[1][q] * C[1][q] + C[2][q] * C[2][q] + C[5][q] * C[5][q]);
  }
  for (int q = 0; q < kLanes; ++q) {
    if (J[q] > 0 && i1[q] > 3.0 * s && (3.0 * s * s - 2.0 * i1[q] * s + i2[q]) > 0 &&
        ((s - i1[q]) * s + i2[q]) * s - J[q] * J[q] < 0)
      continue;
    if (continued) ++*continued;
    materials::Mat3 Fq, Pq;
    for (int i = 0; i < 9; ++i) Fq.a[i] = F[i][q];
    if (materials::StVK{0.5 * m2, lambda}.pk1_continued(Fq, sc, Pq))
      for (int i = 0; i < 9; ++i) P[i][q] = Pq.a[i];
  }
}

// A : A, summed in materials::frobenius_dot's order, and its square root.
GEN4D_ALWAYS_INLINE void lanes_sqnorm(const Lanes A[9], Lanes s) {
  for (int q = 0; q < kLanes; ++q) {
    s[q] = 0;
    for (int i = 0; i < 9; ++i) s[q] += A[i][q] * A[i][q];
  }
}
GEN4D_ALWAYS_INLINE void lanes_norm(const Lanes A[9], Lanes n) {
  lanes_sqnorm(A, n);
  for (int q = 0; q < kLanes; ++q) n[q] = std::sqrt(n[q]);
}

// Neo-Hookean (materials::NeoHookean::pk1):
// P = mu (1 - 1 / (I_C + 1)) F + (lambda (J - 1) - 3/4 mu) cof F.
GEN4D_ALWAYS_INLINE void lanes_neo_hookean(const Lanes F[9], double mu, double lambda, Lanes P[9]) {
  alignas(64) Lanes C[9], J, ic, a, b;
  lanes_cofactor(F, C);
  lanes_det(F, J);
  lanes_sqnorm(F, ic);
  for (int q = 0; q < kLanes; ++q) {
    a[q] = mu * (1.0 - 1.0 / (ic[q] + 1.0));
    b[q] = lambda * (J[q] - 1.0) - 0.75 * mu;
  }
  for (int i = 0; i < 9; ++i)
    for (int q = 0; q < kLanes; ++q) P[i][q] = a[q] * F[i][q] + b[q] * C[i][q];
}

// Fixed corotated (materials::FixedCorotated::pk1): P = 2 mu (F - R) + lambda (J - 1) cof F,
// R the rotation of F = R S by Higham's scaled Newton iteration as
// materials::polar_rotation_newton runs it, every lane to its own convergence (a settled
// lane keeps its value while the others iterate), and the signed SVD's rotation
// (materials::polar_rotation) in a lane where that iteration declines, as the scalar loop
// falls back.
GEN4D_ALWAYS_INLINE void lanes_corotated(const Lanes F[9], double mu, double lambda, Lanes P[9]) {
  alignas(64) Lanes X[9], Xn[9], C[9], d, nX, nC, g, change, act, J;
  lanes_det(F, J);
  lanes_norm(F, nX);
  bool any = false;
  for (int q = 0; q < kLanes; ++q) {
    act[q] = J[q] > 1e-6 * nX[q] * nX[q] * nX[q] ? 1.0 : 0.0;
    any = any || act[q] != 0;
  }
  double ok[kLanes] = {};
  for (int i = 0; i < 9; ++i)
    for (int q = 0; q < kLanes; ++q) X[i][q] = F[i][q];
  for (int it = 0; it < 30 && any; ++it) {
    lanes_cofactor(X, C);
    lanes_det(X, d);
    lanes_norm(C, nC);
    lanes_norm(X, nX);
    for (int q = 0; q < kLanes; ++q) g[q] = std::sqrt(nC[q] / (d[q] * nX[q]));
    for (int i = 0; i < 9; ++i)
      for (int q = 0; q < kLanes; ++q) {
        Xn[i][q] = (0.5 * g[q]) * X[i][q] + (0.5 / (g[q] * d[q])) * C[i][q];
        C[i][q] = Xn[i][q] - X[i][q];  // the step (C is not needed again this iteration)
      }
    lanes_norm(C, change);
    any = false;
    for (int i = 0; i < 9; ++i)
      for (int q = 0; q < kLanes; ++q) X[i][q] = act[q] != 0 ? Xn[i][q] : X[i][q];
    for (int q = 0; q < kLanes; ++q) {
      if (act[q] != 0 && change[q] <= 1e-14) act[q] = 0, ok[q] = 1;
      any = any || act[q] != 0;
    }
  }
  for (int q = 0; q < kLanes; ++q)
    if (ok[q] == 0) {
      materials::Mat3 Fq;
      for (int i = 0; i < 9; ++i) Fq.a[i] = F[i][q];
      const materials::Mat3 R = materials::polar_rotation(Fq);
      for (int i = 0; i < 9; ++i) X[i][q] = R.a[i];
    }
  lanes_cofactor(F, C);
  const double m2 = 2.0 * mu;
  for (int q = 0; q < kLanes; ++q) d[q] = lambda * (J[q] - 1.0);
  for (int i = 0; i < 9; ++i)
    for (int q = 0; q < kLanes; ++q) P[i][q] = m2 * (F[i][q] - X[i][q]) + d[q] * C[i][q];
}

// Linear: e = (F + F^T) / 2 - I, P = 2 mu e + lambda tr(e) I, in the order of
// materials::LinearElastic::pk1 (m2 = 2 mu).
GEN4D_ALWAYS_INLINE void lanes_linear(const Lanes F[9], double m2, double lambda, Lanes P[9]) {
  alignas(64) Lanes tr;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      const double id = r == c ? 1.0 : 0.0;
      for (int q = 0; q < kLanes; ++q)
        P[3 * r + c][q] = 0.5 * (F[3 * r + c][q] + F[3 * c + r][q]) - id;
    }
  for (int q = 0; q < kLanes; ++q) tr[q] = lambda * (P[0][q] + P[4][q] + P[8][q]);
  for (int i = 0; i < 9; ++i) {
    const double id = i % 4 == 0 ? 1.0 : 0.0;
    for (int q = 0; q < kLanes; ++q) P[i][q] = m2 * P[i][q] + tr[q] * id;
  }
}

GEN4D_ALWAYS_INLINE void tangent_body(const ElasticTangent& t, const double x[kShapes][3], double w,
                                      double* Ke) {
  constexpr int n = 3 * kShapes;
  const double m2 = 2.0 * t.mu;
  alignas(64) Lanes F[9], D[9][9];
  lanes_grad(t.G, x, F);
  // dP/dF by central differences, all Gauss points at once.
  const double eps = t.eps;
  for (int j = 0; j < 9; ++j) {
    alignas(64) Lanes Fp[9], Fm[9], Pp[9], Pm[9];
    for (int i = 0; i < 9; ++i)
      for (int q = 0; q < kLanes; ++q) Fp[i][q] = Fm[i][q] = F[i][q];
    for (int q = 0; q < kLanes; ++q) Fp[j][q] += eps, Fm[j][q] -= eps;
    if (t.law == ElasticLaw::NeoHookean) {
      lanes_neo_hookean(Fp, t.mu, t.lambda, Pp);
      lanes_neo_hookean(Fm, t.mu, t.lambda, Pm);
    } else {
      lanes_stvk(Fp, m2, t.lambda, Pp);
      lanes_stvk(Fm, m2, t.lambda, Pm);
    }
    for (int i = 0; i < 9; ++i)
      for (int q = 0; q < kLanes; ++q) D[i][j][q] = (Pp[i][q] - Pm[i][q]) / (2 * eps);
  }
  // Ke(3 l + a, 3 m + b) = sum_q sum_e T_q[l][a][b][e] dN_q[m][e], with
  // T_q[l][a][b][e] = w sum_c dN_q[l][c] Dsym_q[ac][be] (Dsym times 2: the scalar loop's
  // (dN 0.5) (D + D^T)). Vectors run over the shapes (l for T, m for Ke, padded to kPad);
  // every entry gets the scalar loop's terms in its order, so the upper triangle is the
  // scalar loop's bit for bit. The lower one is computed too and then overwritten by the
  // upper, as the scalar loop mirrors it.
  constexpr int kPad = 12;
  const int nshape = t.shapes;
  alignas(64) double K[n][3][kPad] = {};  // row 3 l + a, then b, m
  for (int q = 0; q < kLanes; ++q) {
    alignas(64) double dN[3][kPad] = {}, dNh[3][kPad] = {};
    for (int l = 0; l < nshape; ++l)
      for (int c = 0; c < 3; ++c) dN[c][l] = t.dN[q][l][c], dNh[c][l] = t.dN[q][l][c] * 0.5;
    alignas(64) double T[3][3][3][kPad];  // a, b, e, l
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b)
        for (int e = 0; e < 3; ++e) {
          double X[3];
          for (int c = 0; c < 3; ++c)
            X[c] = D[3 * a + c][3 * b + e][q] + D[3 * b + e][3 * a + c][q];
          for (int l = 0; l < kPad; ++l) {
            double s = 0;
            for (int c = 0; c < 3; ++c) s += dNh[c][l] * X[c];
            T[a][b][e][l] = w * s;
          }
        }
    for (int l = 0; l < nshape; ++l)
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) {
          const double t0 = T[a][b][0][l], t1 = T[a][b][1][l], t2 = T[a][b][2][l];
          double* row = K[3 * l + a][b];
          for (int m = 0; m < kPad; ++m) row[m] += t0 * dN[0][m] + t1 * dN[1][m] + t2 * dN[2][m];
        }
  }
  for (int i = 0; i < n * n; ++i) Ke[i] = 0;
  const int nd = 3 * nshape;
  for (int r = 0; r < nd; ++r)
    for (int m = 0; m < nshape; ++m)
      for (int b = 0; b < 3; ++b) Ke[r + n * (3 * m + b)] = K[r][b][m];
  for (int j = 0; j < nd; ++j)
    for (int i = j + 1; i < nd; ++i) Ke[i + n * j] = Ke[j + n * i];
}

GEN4D_ALWAYS_INLINE void force_pass_body(const ElasticForcePass& p) {
  const bool bubbles = p.alpha != nullptr;
  const bool kv = p.kv_beta != 0;
  const double m2 = 2.0 * p.mu;
  const double kv_m2 = p.kv_beta * 2.0 * p.kv_mu, kv_l = p.kv_beta * p.kv_lambda;
  const double prony_den = 1.0 + p.prony_rate;
  const auto& G = p.G;
  // The gradients by Gauss point, axis and shape (padded with zeros), for the scatter.
  alignas(64) double GT[kLanes][3][kShapePad] = {};
  for (int q = 0; q < kLanes; ++q)
    for (int c = 0; c < 3; ++c)
      for (int l = 0; l < kShapes; ++l) GT[q][c][l] = G[l][c][q];
  double max_mises = p.max_mises ? *p.max_mises : 0.0;
  for (std::size_t vx = 0; vx < p.voxels; ++vx) {
    double xe[kShapes][3] = {}, ve[kShapes][3] = {};
    for (int l = 0; l < 8; ++l) {
      const std::size_t n = static_cast<std::size_t>(p.vox_node[vx][l]);
      for (int d = 0; d < 3; ++d) xe[l][d] = p.X[n][d] + p.u[3 * n + d];
      if (kv)
        for (int d = 0; d < 3; ++d) ve[l][d] = p.v[3 * n + d];
    }
    if (bubbles)
      for (int i = 0; i < 9; ++i) {
        xe[8 + i / 3][i % 3] = p.alpha[9 * vx + static_cast<std::size_t>(i)];
        if (kv) ve[8 + i / 3][i % 3] = p.alpha_rate[9 * vx + static_cast<std::size_t>(i)];
      }
    alignas(64) Lanes F[9], P[9], tr;
    lanes_grad(G, xe, F);
    switch (p.law) {
      case ElasticLaw::NeoHookean:
        lanes_neo_hookean(F, p.mu, p.lambda, P);
        break;
      case ElasticLaw::Corotated:
        lanes_corotated(F, p.mu, p.lambda, P);
        break;
      case ElasticLaw::Linear:
        lanes_linear(F, m2, p.lambda, P);
        break;
      default:
        lanes_stvk(F, m2, p.lambda, P, p.continued);
    }
    if (p.q) {
      // Relaxing part: dq/dt = (g P_el - q) / tau (backward Euler); stress P_el - q.
      for (int q = 0; q < kLanes; ++q) {
        const std::size_t g = 9 * (8 * vx + static_cast<std::size_t>(q));
        for (int i = 0; i < 9; ++i) {
          p.q_new[g + i] = (p.q[g + i] + p.prony_rate_g * P[i][q]) / prony_den;
          P[i][q] -= p.q_new[g + i];
        }
      }
    }
    if (kv) {
      // Viscous stress beta (2 mu Ed + lambda tr(Ed) I) of the Green strain rate
      // Ed = sym(F^T dF/dt), carried by F; under the linear law of Ed = sym(dF/dt), added.
      const bool linear = p.law == ElasticLaw::Linear;
      alignas(64) Lanes Fd[9], Ed[9];
      lanes_grad(G, ve, Fd);
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          for (int q = 0; q < kLanes; ++q) {
            double e = 0;
            if (linear)
              e = Fd[3 * i + j][q] + Fd[3 * j + i][q];
            else
              for (int k = 0; k < 3; ++k)
                e += F[3 * k + i][q] * Fd[3 * k + j][q] + Fd[3 * k + i][q] * F[3 * k + j][q];
            Ed[3 * i + j][q] = 0.5 * e;
          }
      for (int q = 0; q < kLanes; ++q) tr[q] = Ed[0][q] + Ed[4][q] + Ed[8][q];
      for (int i = 0; i < 9; ++i)
        for (int q = 0; q < kLanes; ++q) Ed[i][q] = kv_m2 * Ed[i][q];  // now Sv
      for (int i = 0; i < 3; ++i)
        for (int q = 0; q < kLanes; ++q) Ed[4 * i][q] += kv_l * tr[q];
      if (linear)
        for (int i = 0; i < 9; ++i)
          for (int q = 0; q < kLanes; ++q) P[i][q] += Ed[i][q];
      else
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            for (int q = 0; q < kLanes; ++q)
              P[3 * i + j][q] += F[3 * i][q] * Ed[j][q] + F[3 * i + 1][q] * Ed[3 + j][q] +
                                 F[3 * i + 2][q] * Ed[6 + j][q];
    }
    const double f = p.vfac[vx];
    for (int i = 0; i < 9; ++i)
      for (int q = 0; q < kLanes; ++q) P[i][q] *= f;
    if (p.max_mises) {
      for (int q = 0; q < kLanes; ++q) {
        double tau[9];
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            tau[3 * i + j] = P[3 * i][q] * F[3 * j][q] + P[3 * i + 1][q] * F[3 * j + 1][q] +
                             P[3 * i + 2][q] * F[3 * j + 2][q];
        max_mises = std::max(max_mises, mises(tau));
      }
    }
    // fe_l += w P grad N_l per Gauss point, the points summed in order; the shapes are the
    // lanes here (a sum across the Gauss-point lanes would run one lane at a time).
    alignas(64) double fs[3][kShapePad] = {};
    for (int q = 0; q < kLanes; ++q)
      for (int a = 0; a < 3; ++a) {
        const double p0 = P[3 * a][q], p1 = P[3 * a + 1][q], p2 = P[3 * a + 2][q];
        for (int l = 0; l < kShapePad; ++l)
          fs[a][l] += p.weight * (p0 * GT[q][0][l] + p1 * GT[q][1][l] + p2 * GT[q][2][l]);
      }
    double fe[kShapes][3];
    for (int l = 0; l < kShapes; ++l)
      for (int a = 0; a < 3; ++a) fe[l][a] = fs[a][l];
    for (int l = 0; l < 8; ++l) {
      const std::size_t n = static_cast<std::size_t>(p.vox_node[vx][l]);
      for (int i = 0; i < 3; ++i) p.fint[3 * n + i] += fe[l][i];
    }
    if (bubbles)
      for (int i = 0; i < 9; ++i)
        p.ral[9 * vx + static_cast<std::size_t>(i)] = fe[8 + i / 3][i % 3];
  }
  if (p.max_mises) *p.max_mises = max_mises;
}

// The condensed bubbles' products, with 4 output rows a vector; each output sums its terms as
// the scalar products of Eigen's SSE2 GEMV kernels do (see ElementKernel.hpp). Without AVX
// (kVector false) the loops are scalar: the baseline build's 4-lane vectors went through the
// stack there, and a run's bubble products took 3x as long (bench_diagnose --isa baseline).
template <bool kVector>
GEN4D_ALWAYS_INLINE void bubble_lt_body(const double* Lt, const double* r, double* out) {
  if constexpr (kVector) {
    for (int i = 0; i < 24; i += 4) {
      V4 c0 = splat4(0.0), c1 = splat4(0.0);
      for (int j = 0; j < 8; j += 2) {
        c0 = load4(Lt + i + 24 * j) * r[j] + c0;
        c1 = load4(Lt + i + 24 * (j + 1)) * r[j + 1] + c1;
      }
      V4 cc = c0 + c1;
      cc = cc + load4(Lt + i + 24 * 8) * r[8];
      store4(out + i, splat4(0.0) + cc);
    }
  } else {
    for (int i = 0; i < 24; ++i) {
      double c0 = 0, c1 = 0;
      for (int j = 0; j < 8; j += 2) {
        c0 = Lt[i + 24 * j] * r[j] + c0;
        c1 = Lt[i + 24 * (j + 1)] * r[j + 1] + c1;
      }
      double cc = c0 + c1;
      cc += Lt[i + 24 * 8] * r[8];
      out[i] = 0.0 + cc;
    }
  }
}

template <int Cols, bool kVector>
GEN4D_ALWAYS_INLINE void bubble_times_body(const double* A, const double* x, double s,
                                           double* out) {
  if constexpr (kVector) {
    V4 c0 = splat4(0.0), c1 = splat4(0.0);
    double c8 = 0;
    for (int j = 0; j < Cols; ++j) {
      const double* col = A + 9 * j;
      c0 = load4(col) * x[j] + c0;
      c1 = load4(col + 4) * x[j] + c1;
      c8 = col[8] * x[j] + c8;
    }
    store4(out, c0 * s + splat4(0.0));
    store4(out + 4, c1 * s + splat4(0.0));
    out[8] = c8 * s + 0.0;
  } else {
    double c[9] = {};
    for (int j = 0; j < Cols; ++j)
      for (int i = 0; i < 9; ++i) c[i] = A[i + 9 * j] * x[j] + c[i];
    for (int i = 0; i < 9; ++i) out[i] = c[i] * s + 0.0;
  }
}

// One entry point per instruction set, each the same source.
void force_pass_baseline(const ElasticForcePass& p) {
  force_pass_body(p);
}
void tangent_baseline(const ElasticTangent& t, const double x[kShapes][3], double w, double* Ke) {
  tangent_body(t, x, w, Ke);
}
void bubble_lt_baseline(const double* Lt, const double* r, double* out) {
  bubble_lt_body<false>(Lt, r, out);
}
void bubble_l_baseline(const double* L, const double* x, double s, double* out) {
  bubble_times_body<24, false>(L, x, s, out);
}
void bubble_k_baseline(const double* K, const double* x, double s, double* out) {
  bubble_times_body<9, false>(K, x, s, out);
}
#if GEN4D_X86_ISAS
__attribute__((target("avx2"))) void force_pass_avx2(const ElasticForcePass& p) {
  force_pass_body(p);
}
__attribute__((target("avx2"))) void tangent_avx2(const ElasticTangent& t,
                                                  const double x[kShapes][3], double w,
                                                  double* Ke) {
  tangent_body(t, x, w, Ke);
}
__attribute__((target("avx2"))) void bubble_lt_avx2(const double* Lt, const double* r,
                                                    double* out) {
  bubble_lt_body<true>(Lt, r, out);
}
__attribute__((target("avx2"))) void bubble_l_avx2(const double* L, const double* x, double s,
                                                   double* out) {
  bubble_times_body<24, true>(L, x, s, out);
}
__attribute__((target("avx2"))) void bubble_k_avx2(const double* K, const double* x, double s,
                                                   double* out) {
  bubble_times_body<9, true>(K, x, s, out);
}
__attribute__((target("avx512f"))) void force_pass_avx512(const ElasticForcePass& p) {
  force_pass_body(p);
}
__attribute__((target("avx512f"))) void tangent_avx512(const ElasticTangent& t,
                                                       const double x[kShapes][3], double w,
                                                       double* Ke) {
  tangent_body(t, x, w, Ke);
}
#endif

struct Kernels {
  const char* isa;
  void (*force_pass)(const ElasticForcePass&);
  void (*tangent)(const ElasticTangent&, const double[kShapes][3], double, double*);
  void (*bubble_lt)(const double*, const double*, double*);
  void (*bubble_l)(const double*, const double*, double, double*);
  void (*bubble_k)(const double*, const double*, double, double*);
};

const Kernels kBaseline{"baseline",         force_pass_baseline, tangent_baseline,
                        bubble_lt_baseline, bubble_l_baseline,   bubble_k_baseline};
#if GEN4D_X86_ISAS
const Kernels kAvx2{"avx2",         force_pass_avx2, tangent_avx2,
                    bubble_lt_avx2, bubble_l_avx2,   bubble_k_avx2};
// The bubbles' products are too small for 8 lanes: the AVX-512 set takes the AVX2 ones.
const Kernels kAvx512{"avx512f",      force_pass_avx512, tangent_avx512,
                      bubble_lt_avx2, bubble_l_avx2,     bubble_k_avx2};
#endif

// AVX2 first (IsaDispatch): on the AVX-512 machine measured (AMD EPYC, bench_diagnose --isa),
// the AVX-512 build's force pass was no faster and its tangent 1.5x slower (0.38-0.47 s
// against 0.24-0.28 s a run). AVX-512 stays selectable.
#if GEN4D_X86_ISAS
IsaDispatch<Kernels> g_kernels({&kBaseline, &kAvx2, &kAvx512}, "element kernel");
#else
IsaDispatch<Kernels> g_kernels({&kBaseline}, "element kernel");
#endif

}  // namespace

void elastic_force_pass(const ElasticForcePass& p) {
  g_kernels->force_pass(p);
}

void elastic_element_tangent(const ElasticTangent& t, const double x[kShapes][3], double w,
                             double* Ke) {
  g_kernels->tangent(t, x, w, Ke);
}

void bubble_lt_times(const double* Lt, const double* r, double* out) {
  g_kernels->bubble_lt(Lt, r, out);
}
void bubble_l_times(const double* L, const double* x, double s, double* out) {
  g_kernels->bubble_l(L, x, s, out);
}
void bubble_kinv_times(const double* Kinv, const double* x, double s, double* out) {
  g_kernels->bubble_k(Kinv, x, s, out);
}

std::vector<std::string> element_kernel_isas() {
  return g_kernels.isas();
}

std::string element_kernel_isa() {
  return g_kernels->isa;
}

void set_element_kernel_isa(const std::string& isa) {
  g_kernels.set(isa);
}

}  // namespace gen4d::forward
