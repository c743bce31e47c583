//! Plain-old-data 3x3 matrix and 3-vector (double, row-major) for host/device kernels.
#pragma once

#include <cmath>

#include "materials/Hd.hpp"

namespace gen4d::materials {

//! 3-vector; aggregate so it can live in device arrays and be memcpy'd.
struct Vec3 {
  double v[3];
  GEN4D_HD double& operator[](int i) { return v[i]; }
  GEN4D_HD double operator[](int i) const { return v[i]; }
};

//! Row-major 3x3 matrix: a[3 * row + col], the layout of the batched arrays.
struct Mat3 {
  double a[9];
  GEN4D_HD double& operator()(int r, int c) { return a[3 * r + c]; }
  GEN4D_HD double operator()(int r, int c) const { return a[3 * r + c]; }
};

GEN4D_HD inline Mat3 identity3() {
  return Mat3{{1, 0, 0, 0, 1, 0, 0, 0, 1}};
}

GEN4D_HD inline Mat3 diag3(const Vec3& d) {
  return Mat3{{d[0], 0, 0, 0, d[1], 0, 0, 0, d[2]}};
}

GEN4D_HD inline Mat3 operator+(const Mat3& A, const Mat3& B) {
  Mat3 C;
  for (int i = 0; i < 9; ++i) C.a[i] = A.a[i] + B.a[i];
  return C;
}

GEN4D_HD inline Mat3 operator-(const Mat3& A, const Mat3& B) {
  Mat3 C;
  for (int i = 0; i < 9; ++i) C.a[i] = A.a[i] - B.a[i];
  return C;
}

GEN4D_HD inline Mat3 operator*(double s, const Mat3& A) {
  Mat3 C;
  for (int i = 0; i < 9; ++i) C.a[i] = s * A.a[i];
  return C;
}

//! Matrix product A B.
GEN4D_HD inline Mat3 operator*(const Mat3& A, const Mat3& B) {
  Mat3 C;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) C(r, c) = A(r, 0) * B(0, c) + A(r, 1) * B(1, c) + A(r, 2) * B(2, c);
  return C;
}

GEN4D_HD inline Vec3 operator*(const Mat3& A, const Vec3& x) {
  return Vec3{{A(0, 0) * x[0] + A(0, 1) * x[1] + A(0, 2) * x[2],
               A(1, 0) * x[0] + A(1, 1) * x[1] + A(1, 2) * x[2],
               A(2, 0) * x[0] + A(2, 1) * x[1] + A(2, 2) * x[2]}};
}

GEN4D_HD inline Mat3 transpose(const Mat3& A) {
  return Mat3{{A(0, 0), A(1, 0), A(2, 0), A(0, 1), A(1, 1), A(2, 1), A(0, 2), A(1, 2), A(2, 2)}};
}

//! Cofactor matrix, cof(A) = det(A) A^{-T} wherever A is invertible, and defined everywhere.
GEN4D_HD inline Mat3 cofactor(const Mat3& A) {
  return Mat3{{A(1, 1) * A(2, 2) - A(1, 2) * A(2, 1), A(1, 2) * A(2, 0) - A(1, 0) * A(2, 2),
               A(1, 0) * A(2, 1) - A(1, 1) * A(2, 0), A(0, 2) * A(2, 1) - A(0, 1) * A(2, 2),
               A(0, 0) * A(2, 2) - A(0, 2) * A(2, 0), A(0, 1) * A(2, 0) - A(0, 0) * A(2, 1),
               A(0, 1) * A(1, 2) - A(0, 2) * A(1, 1), A(0, 2) * A(1, 0) - A(0, 0) * A(1, 2),
               A(0, 0) * A(1, 1) - A(0, 1) * A(1, 0)}};
}

GEN4D_HD inline double det(const Mat3& A) {
  return A(0, 0) * (A(1, 1) * A(2, 2) - A(1, 2) * A(2, 1)) -
         A(0, 1) * (A(1, 0) * A(2, 2) - A(1, 2) * A(2, 0)) +
         A(0, 2) * (A(1, 0) * A(2, 1) - A(1, 1) * A(2, 0));
}

//! Frobenius inner product A : B.
GEN4D_HD inline double frobenius_dot(const Mat3& A, const Mat3& B) {
  double s = 0;
  for (int i = 0; i < 9; ++i) s += A.a[i] * B.a[i];
  return s;
}

GEN4D_HD inline double frobenius_norm(const Mat3& A) {
  return std::sqrt(frobenius_dot(A, A));
}

//! U diag(sigma) V^T, the inverse of svd3.
GEN4D_HD inline Mat3 compose_svd(const Mat3& U, const Vec3& sigma, const Mat3& V) {
  Mat3 C;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      C(r, c) = U(r, 0) * sigma[0] * V(c, 0) + U(r, 1) * sigma[1] * V(c, 1) +
                U(r, 2) * sigma[2] * V(c, 2);
  return C;
}

}  // namespace gen4d::materials
