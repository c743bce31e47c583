//! Signed (inversion-safe) 3x3 SVD with a fixed operation count, for host and device.
//
// F = U diag(sigma) V^T with U, V proper rotations, |sigma_0| >= |sigma_1| >= |sigma_2| and only
// sigma_2 allowed to be negative (it carries the sign of det F). The method follows McAdams et al.
// 2011 ("Computing the SVD of 3x3 matrices with minimal branching"), in double precision and with
// exact rather than approximate Givens angles:
//   1. V from a fixed number of cyclic one-sided Jacobi sweeps, i.e. Jacobi on F^T F carried out
//      on the columns of B = F V (more accurate than forming F^T F when F is ill-conditioned);
//   2. columns of B = F V sorted by norm with conditional swaps that keep det V = +1;
//   3. U and sigma from a Givens QR of B. The QR, not sqrt(eig(F^T F)), yields sigma, so small
//      singular values keep absolute accuracy eps*|sigma_0| and rank-deficient F still gets an
//      orthonormal U.
// Every "branch" is a ternary select on data, so GPU threads never diverge.
#pragma once

#include <cmath>
#include <cstddef>

#include "materials/Hd.hpp"
#include "materials/Mat3.hpp"

namespace gen4d::materials {

//! Cyclic one-sided Jacobi sweeps. Convergence is quadratic once the columns are nearly
//! orthogonal; the test suite checks that one sweep fewer already reaches rounding level.
inline constexpr int kSvdJacobiSweeps = 5;

//! Arithmetic of the number type T the SVD runs on: double, or (host only, Svd3Batch.cpp) a
//! vector of lanes, each lane one matrix. Every branch of the method is a select, so a lane
//! computes exactly what the scalar code computes for its matrix.
template <class T>
struct SvdOps;

template <>
struct SvdOps<double> {
  GEN4D_HD static double splat(double x) { return x; }
  GEN4D_HD static double sqrt(double x) { return std::sqrt(x); }
  GEN4D_HD static double abs(double x) { return std::fabs(x); }
  GEN4D_HD static double select(bool c, double a, double b) { return c ? a : b; }
};

namespace detail {

// Matrices are row-major arrays of 9 T: m[3 * row + col].

// One-sided (Hestenes) Jacobi rotation J in the (p, q) plane that makes columns p and q of B
// orthogonal: B <- B J, V <- V J. The 2x2 Gram entries come from the current columns rather than
// from a precomputed F^T F, so their rounding is relative to |b_p| |b_q| instead of |F|^2; that
// keeps the reconstruction at eps |F| when F is ill-conditioned (tested at condition number 1e12).
// Uses the Golub-Van Loan angle (|theta| <= pi/4), written so that orthogonal columns give J = I.
template <class T>
GEN4D_HD inline void jacobi_rotate_columns(T* B, T* V, int p, int q) {
  using O = SvdOps<T>;
  T app = O::splat(0.0), aqq = O::splat(0.0), apq = O::splat(0.0);
  for (int i = 0; i < 3; ++i) {
    app += B[3 * i + p] * B[3 * i + p];
    aqq += B[3 * i + q] * B[3 * i + q];
    apq += B[3 * i + p] * B[3 * i + q];
  }
  const T tau = aqq - app;
  const T denom = O::abs(tau) + O::sqrt(tau * tau + 4.0 * apq * apq);
  const T sign_tau = O::select(tau >= O::splat(0.0), O::splat(1.0), O::splat(-1.0));
  const T t = O::select(denom > O::splat(0.0), 2.0 * apq * sign_tau / denom, O::splat(0.0));
  const T c = 1.0 / O::sqrt(1.0 + t * t);
  const T s = t * c;
  for (int i = 0; i < 3; ++i) {
    const T bp = B[3 * i + p], bq = B[3 * i + q];
    B[3 * i + p] = c * bp - s * bq;
    B[3 * i + q] = s * bp + c * bq;
    const T vp = V[3 * i + p], vq = V[3 * i + q];
    V[3 * i + p] = c * vp - s * vq;
    V[3 * i + q] = s * vp + c * vq;
  }
}

//! `sweeps` cyclic one-sided Jacobi sweeps: B <- B V with V a rotation and B's columns orthogonal.
template <class T>
GEN4D_HD inline void jacobi_orthogonalize(T* B, T* V, int sweeps) {
  for (int i = 0; i < 9; ++i) V[i] = SvdOps<T>::splat(i % 4 == 0 ? 1.0 : 0.0);
  for (int k = 0; k < sweeps; ++k) {
    jacobi_rotate_columns(B, V, 0, 1);
    jacobi_rotate_columns(B, V, 0, 2);
    jacobi_rotate_columns(B, V, 1, 2);
  }
}
GEN4D_HD inline void jacobi_orthogonalize(Mat3& B, Mat3& V, int sweeps) {
  jacobi_orthogonalize<double>(B.a, V.a, sweeps);
}

// When `swap`, columns (i, j) of B and V become (j, -i): a reordering with det V kept at +1.
template <class T, class Mask>
GEN4D_HD inline void swap_columns_if(Mask swap, T* B, T* V, T* rho, int i, int j) {
  using O = SvdOps<T>;
  for (int row = 0; row < 3; ++row) {
    const T bi = B[3 * row + i], bj = B[3 * row + j];
    B[3 * row + i] = O::select(swap, bj, bi);
    B[3 * row + j] = O::select(swap, -bi, bj);
    const T vi = V[3 * row + i], vj = V[3 * row + j];
    V[3 * row + i] = O::select(swap, vj, vi);
    V[3 * row + j] = O::select(swap, -vi, vj);
  }
  const T ri = rho[i], rj = rho[j];
  rho[i] = O::select(swap, rj, ri);
  rho[j] = O::select(swap, ri, rj);
}

// Givens rotation on rows (p, q) of R that zeroes R(q, col) and leaves R(p, col) >= 0;
// U accumulates the transposes so that U R stays constant. Below `tiny` (inputs are
// normalised to max entry 1) the pair is numerically zero and the identity keeps U orthonormal
// where squaring would underflow.
template <class T>
GEN4D_HD inline void givens_qr_step(T* R, T* U, int p, int q, int col) {
  using O = SvdOps<T>;
  const T a = R[3 * p + col], b = R[3 * q + col];
  const T rho = O::sqrt(a * a + b * b);
  const auto live = rho > O::splat(1e-150);
  const T c = O::select(live, a / rho, O::splat(1.0));
  const T s = O::select(live, b / rho, O::splat(0.0));
  for (int k = 0; k < 3; ++k) {
    const T rp = R[3 * p + k], rq = R[3 * q + k];
    R[3 * p + k] = c * rp + s * rq;
    R[3 * q + k] = -s * rp + c * rq;
    const T up = U[3 * k + p], uq = U[3 * k + q];
    U[3 * k + p] = c * up + s * uq;
    U[3 * k + q] = -s * up + c * uq;
  }
}

//! Signed SVD F = U diag(sigma) V^T of one matrix per lane of T (see the file comment).
template <class T>
GEN4D_HD inline void svd3_generic(const T* F, T* U, T* sigma, T* V) {
  using O = SvdOps<T>;
  // Normalising by the largest entry makes the thresholds scale-free and keeps F^T F finite.
  T scale = O::splat(0.0);
  for (int i = 0; i < 9; ++i) scale = O::select(O::abs(F[i]) > scale, O::abs(F[i]), scale);
  scale = O::select(scale > O::splat(0.0), scale, O::splat(1.0));
  T B[9];
  for (int i = 0; i < 9; ++i) B[i] = F[i] / scale;

  jacobi_orthogonalize(B, V, kSvdJacobiSweeps);

  T rho[3];
  for (int c = 0; c < 3; ++c) rho[c] = B[c] * B[c] + B[3 + c] * B[3 + c] + B[6 + c] * B[6 + c];
  swap_columns_if(rho[0] < rho[1], B, V, rho, 0, 1);
  swap_columns_if(rho[0] < rho[2], B, V, rho, 0, 2);
  swap_columns_if(rho[1] < rho[2], B, V, rho, 1, 2);

  for (int i = 0; i < 9; ++i) U[i] = O::splat(i % 4 == 0 ? 1.0 : 0.0);
  givens_qr_step(B, U, 0, 1, 0);
  givens_qr_step(B, U, 0, 2, 0);
  givens_qr_step(B, U, 1, 2, 1);

  // B is now R = U^T F V: upper triangular with off-diagonals at rounding level, so its diagonal
  // is sigma. Rounding can leave neighbours out of order by an ulp of sigma_0; raising the
  // smaller one keeps the ordering exact at that same ulp-level cost.
  const T s2 = B[8];
  const T s1 = O::select(B[4] > O::abs(s2), B[4], O::abs(s2));
  const T s0 = O::select(B[0] > s1, B[0], s1);
  sigma[0] = s0 * scale;
  sigma[1] = s1 * scale;
  sigma[2] = s2 * scale;
}

}  // namespace detail

//! Signed SVD F = U diag(sigma) V^T (see the file comment for the conventions).
GEN4D_HD inline void svd3(const Mat3& F, Mat3& U, Vec3& sigma, Mat3& V) {
  detail::svd3_generic<double>(F.a, U.a, sigma.v, V.a);
}

//! Rotation R = U V^T of the signed SVD: the closest proper rotation to F, also for det F < 0.
GEN4D_HD inline Mat3 polar_rotation(const Mat3& F) {
  Mat3 U, V;
  Vec3 sigma;
  svd3(F, U, sigma, V);
  return U * transpose(V);
}

//! Rotation R of the polar decomposition F = R S by Higham's scaled Newton iteration
//! X <- (g X + X^-T / g) / 2, g = (|X^-1|_F / |X|_F)^(1/2): a handful of 3x3 cofactor
//! inversions instead of a Jacobi SVD (the implicit diagnose model calls it at every Gauss point
//! of every Newton iterate). Equal to polar_rotation(F) to rounding where det F > 0. Returns
//! false, R untouched, where F is inverted or nearly flat (det F <= 1e-6 |F|^3) or the iteration
//! has not settled in 30 steps; callers then take polar_rotation (the signed SVD's rotation).
GEN4D_HD inline bool polar_rotation_newton(const Mat3& F, Mat3& R) {
  const double nF = frobenius_norm(F);
  if (!(det(F) > 1e-6 * nF * nF * nF)) return false;
  Mat3 X = F;
  for (int it = 0; it < 30; ++it) {
    const Mat3 C = cofactor(X);  // det(X) X^-T
    const double d = det(X);
    const double g = std::sqrt(frobenius_norm(C) / (d * frobenius_norm(X)));
    const Mat3 Xn = (0.5 * g) * X + (0.5 / (g * d)) * C;
    const double change = frobenius_norm(Xn - X);
    X = Xn;
    if (change <= 1e-14) {
      R = X;
      return true;
    }
  }
  return false;
}

//! svd3 over n row-major 3x3 matrices stored back to back (9 doubles each, 3 per sigma),
//! several matrices at a time in vector lanes: 8 with AVX-512, 4 with AVX2 or SSE2, the best
//! the CPU has. Each result equals svd3's for that matrix in every bit (the lanes run svd3's
//! operations, without fused multiply-adds), whatever its neighbours in the batch and whichever
//! instruction set. Host only (Svd3Batch.cpp).
void svd3_batch(std::size_t n, const double* F, double* U, double* sigma, double* V);

enum class SvdIsa { kSse2 = 0, kAvx2 = 1, kAvx512 = 2 };
//! The best instruction set svd3_batch can use on this CPU.
SvdIsa svd3_batch_best_isa();
//! svd3_batch on `isa` (or the best one below it the CPU has): for tests and benchmarks.
void svd3_batch(std::size_t n, const double* F, double* U, double* sigma, double* V, SvdIsa isa);

}  // namespace gen4d::materials
