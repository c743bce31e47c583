// svd3_batch: svd3 on vector lanes, one matrix per lane (see Svd3.hpp). Built with
// -ffp-contract=off and -fno-math-errno (src/CMakeLists.txt): no fused multiply-adds, so each
// lane rounds exactly as the scalar svd3 does, and sqrt is the vector instruction.
#include <cstddef>

#include "materials/Svd3.hpp"

namespace gen4d::materials {

//! W doubles (GCC vector extension), one matrix per lane: 4 fill two SSE2 registers or one
//! AVX2 register, 8 one AVX-512 register.
template <int W>
struct LanesOf {
  typedef double type __attribute__((vector_size(8 * W)));
  typedef long mask __attribute__((vector_size(8 * W)));
};

template <int W>
struct SvdOpsLanes {
  using T = typename LanesOf<W>::type;
  static T splat(double x) { return T{} + x; }
  static T sqrt(T x) {
    T r;
    for (int l = 0; l < W; ++l) r[l] = __builtin_sqrt(x[l]);
    return r;
  }
  static T abs(T x) {
    T r;
    for (int l = 0; l < W; ++l) r[l] = __builtin_fabs(x[l]);
    return r;
  }
  static T select(typename LanesOf<W>::mask c, T a, T b) { return c ? a : b; }
};

template <>
struct SvdOps<LanesOf<4>::type> : SvdOpsLanes<4> {};
template <>
struct SvdOps<LanesOf<8>::type> : SvdOpsLanes<8> {};

namespace {

// Matrices i0 .. i0 + count (count <= W); the lanes beyond count hold the identity.
template <int W>
inline void svd3_lanes(std::size_t i0, std::size_t count, const double* F, double* U, double* sigma,
                       double* V) {
  using T = typename LanesOf<W>::type;
  T f[9], u[9], s[3], v[9];
  for (int k = 0; k < 9; ++k)
    for (int l = 0; l < W; ++l)
      f[k][l] =
          static_cast<std::size_t>(l) < count ? F[9 * (i0 + l) + k] : (k % 4 == 0 ? 1.0 : 0.0);
  detail::svd3_generic<T>(f, u, s, v);
  for (std::size_t l = 0; l < count; ++l) {
    for (int k = 0; k < 9; ++k) {
      U[9 * (i0 + l) + k] = u[k][l];
      V[9 * (i0 + l) + k] = v[k][l];
    }
    for (int k = 0; k < 3; ++k) sigma[3 * (i0 + l) + k] = s[k][l];
  }
}

template <int W>
inline void batch(std::size_t n, const double* F, double* U, double* sigma, double* V) {
  for (std::size_t i = 0; i < n; i += W) svd3_lanes<W>(i, n - i < W ? n - i : W, F, U, sigma, V);
}

__attribute__((target("avx512f"), flatten)) void batch_avx512(std::size_t n, const double* F,
                                                              double* U, double* sigma, double* V) {
  batch<8>(n, F, U, sigma, V);
}

__attribute__((target("avx2"), flatten)) void batch_avx2(std::size_t n, const double* F, double* U,
                                                         double* sigma, double* V) {
  batch<4>(n, F, U, sigma, V);
}

__attribute__((flatten)) void batch_sse2(std::size_t n, const double* F, double* U, double* sigma,
                                         double* V) {
  batch<4>(n, F, U, sigma, V);
}

}  // namespace

SvdIsa svd3_batch_best_isa() {
  static const SvdIsa best = __builtin_cpu_supports("avx512f") ? SvdIsa::kAvx512
                             : __builtin_cpu_supports("avx2")  ? SvdIsa::kAvx2
                                                               : SvdIsa::kSse2;
  return best;
}

void svd3_batch(std::size_t n, const double* F, double* U, double* sigma, double* V, SvdIsa isa) {
  if (isa > svd3_batch_best_isa()) isa = svd3_batch_best_isa();
  if (isa == SvdIsa::kAvx512)
    batch_avx512(n, F, U, sigma, V);
  else if (isa == SvdIsa::kAvx2)
    batch_avx2(n, F, U, sigma, V);
  else
    batch_sse2(n, F, U, sigma, V);
}

void svd3_batch(std::size_t n, const double* F, double* U, double* sigma, double* V) {
  svd3_batch(n, F, U, sigma, V, svd3_batch_best_isa());
}

}  // namespace gen4d::materials
