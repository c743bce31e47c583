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

namespace detail {

// One-sided (Hestenes) Jacobi rotation J in the (p, q) plane that makes columns p and q of B
// orthogonal: B <- B J, V <- V J. The 2x2 Gram entries come from the current columns rather than
// from a precomputed F^T F, so their rounding is relative to |b_p| |b_q| instead of |F|^2; that
// keeps the reconstruction at eps |F| when F is ill-conditioned (tested at condition number 1e12).
// Uses the Golub-Van Loan angle (|theta| <= pi/4), written so that orthogonal columns give J = I.
GEN4D_HD inline void jacobi_rotate_columns(Mat3& B, Mat3& V, int p, int q) {
  double app = 0.0, aqq = 0.0, apq = 0.0;
  for (int i = 0; i < 3; ++i) {
    app += B(i, p) * B(i, p);
    aqq += B(i, q) * B(i, q);
    apq += B(i, p) * B(i, q);
  }
  const double tau = aqq - app;
  const double denom = std::fabs(tau) + std::sqrt(tau * tau + 4.0 * apq * apq);
  const double sign_tau = tau >= 0.0 ? 1.0 : -1.0;
  const double t = denom > 0.0 ? 2.0 * apq * sign_tau / denom : 0.0;
  const double c = 1.0 / std::sqrt(1.0 + t * t);
  const double s = t * c;
  for (int i = 0; i < 3; ++i) {
    const double bp = B(i, p), bq = B(i, q);
    B(i, p) = c * bp - s * bq;
    B(i, q) = s * bp + c * bq;
    const double vp = V(i, p), vq = V(i, q);
    V(i, p) = c * vp - s * vq;
    V(i, q) = s * vp + c * vq;
  }
}

//! `sweeps` cyclic one-sided Jacobi sweeps: B <- B V with V a rotation and B's columns orthogonal.
GEN4D_HD inline void jacobi_orthogonalize(Mat3& B, Mat3& V, int sweeps) {
  V = identity3();
  for (int k = 0; k < sweeps; ++k) {
    jacobi_rotate_columns(B, V, 0, 1);
    jacobi_rotate_columns(B, V, 0, 2);
    jacobi_rotate_columns(B, V, 1, 2);
  }
}

// When `swap`, columns (i, j) of B and V become (j, -i): a reordering with det V kept at +1.
GEN4D_HD inline void swap_columns_if(bool swap, Mat3& B, Mat3& V, double* rho, int i, int j) {
  for (int row = 0; row < 3; ++row) {
    const double bi = B(row, i), bj = B(row, j);
    B(row, i) = swap ? bj : bi;
    B(row, j) = swap ? -bi : bj;
    const double vi = V(row, i), vj = V(row, j);
    V(row, i) = swap ? vj : vi;
    V(row, j) = swap ? -vi : vj;
  }
  const double ri = rho[i], rj = rho[j];
  rho[i] = swap ? rj : ri;
  rho[j] = swap ? ri : rj;
}

// Givens rotation on rows (p, q) of R that zeroes R(q, col) and leaves R(p, col) >= 0;
// U accumulates the transposes so that U R stays constant. Below `tiny` (inputs are
// normalised to max entry 1) the pair is numerically zero and the identity keeps U orthonormal
// where squaring would underflow.
GEN4D_HD inline void givens_qr_step(Mat3& R, Mat3& U, int p, int q, int col) {
  constexpr double tiny = 1e-150;
  const double a = R(p, col), b = R(q, col);
  const double rho = std::sqrt(a * a + b * b);
  const bool live = rho > tiny;
  const double c = live ? a / rho : 1.0;
  const double s = live ? b / rho : 0.0;
  for (int k = 0; k < 3; ++k) {
    const double rp = R(p, k), rq = R(q, k);
    R(p, k) = c * rp + s * rq;
    R(q, k) = -s * rp + c * rq;
    const double up = U(k, p), uq = U(k, q);
    U(k, p) = c * up + s * uq;
    U(k, q) = -s * up + c * uq;
  }
}

}  // namespace detail

//! Signed SVD F = U diag(sigma) V^T (see the file comment for the conventions).
GEN4D_HD inline void svd3(const Mat3& F, Mat3& U, Vec3& sigma, Mat3& V) {
  // Normalising by the largest entry makes the thresholds scale-free and keeps F^T F finite.
  double scale = 0.0;
  for (int i = 0; i < 9; ++i) scale = std::fabs(F.a[i]) > scale ? std::fabs(F.a[i]) : scale;
  scale = scale > 0.0 ? scale : 1.0;
  Mat3 Fn;
  for (int i = 0; i < 9; ++i) Fn.a[i] = F.a[i] / scale;

  Mat3 B = Fn;
  detail::jacobi_orthogonalize(B, V, kSvdJacobiSweeps);

  double rho[3];
  for (int c = 0; c < 3; ++c) rho[c] = B(0, c) * B(0, c) + B(1, c) * B(1, c) + B(2, c) * B(2, c);
  detail::swap_columns_if(rho[0] < rho[1], B, V, rho, 0, 1);
  detail::swap_columns_if(rho[0] < rho[2], B, V, rho, 0, 2);
  detail::swap_columns_if(rho[1] < rho[2], B, V, rho, 1, 2);

  U = identity3();
  detail::givens_qr_step(B, U, 0, 1, 0);
  detail::givens_qr_step(B, U, 0, 2, 0);
  detail::givens_qr_step(B, U, 1, 2, 1);

  // B is now R = U^T F V: upper triangular with off-diagonals at rounding level, so its diagonal
  // is sigma. Rounding can leave neighbours out of order by an ulp of sigma_0; raising the
  // smaller one keeps the ordering exact at that same ulp-level cost.
  const double s2 = B(2, 2);
  const double s1 = B(1, 1) > std::fabs(s2) ? B(1, 1) : std::fabs(s2);
  const double s0 = B(0, 0) > s1 ? B(0, 0) : s1;
  sigma = Vec3{{s0 * scale, s1 * scale, s2 * scale}};
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

//! svd3 over n row-major 3x3 matrices stored back to back (9 doubles each, 3 per sigma).
inline void svd3_batch(std::size_t n, const double* F, double* U, double* sigma, double* V) {
  for (std::size_t i = 0; i < n; ++i) {
    Mat3 f, u, v;
    Vec3 s;
    for (int k = 0; k < 9; ++k) f.a[k] = F[9 * i + k];
    svd3(f, u, s, v);
    for (int k = 0; k < 9; ++k) {
      U[9 * i + k] = u.a[k];
      V[9 * i + k] = v.a[k];
    }
    for (int k = 0; k < 3; ++k) sigma[3 * i + k] = s[k];
  }
}

}  // namespace gen4d::materials
