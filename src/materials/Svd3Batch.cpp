// svd3_batch: svd3 on vector lanes, one matrix per lane (see Svd3.hpp). Built with
// -ffp-contract=off and -fno-math-errno (src/CMakeLists.txt): no fused multiply-adds, so each
// lane rounds exactly as the scalar svd3 does, and sqrt is the vector instruction.
#include <cstring>

#include "materials/Svd3.hpp"

namespace gen4d::materials {

//! Four doubles (GCC vector extension): two SSE2 registers, or one AVX2 register.
typedef double Lanes __attribute__((vector_size(32)));
typedef long LaneMask __attribute__((vector_size(32)));
constexpr int kLanes = 4;

template <>
struct SvdOps<Lanes> {
  static Lanes splat(double x) { return Lanes{x, x, x, x}; }
  static Lanes sqrt(Lanes x) {
    Lanes r;
    for (int l = 0; l < kLanes; ++l) r[l] = __builtin_sqrt(x[l]);
    return r;
  }
  static Lanes abs(Lanes x) {
    Lanes r;
    for (int l = 0; l < kLanes; ++l) r[l] = __builtin_fabs(x[l]);
    return r;
  }
  static Lanes select(LaneMask c, Lanes a, Lanes b) { return c ? a : b; }
};

namespace {

// Matrices i0 .. i0 + count (count <= kLanes); the lanes beyond count hold the identity.
template <int Dummy>
inline void svd3_lanes(std::size_t i0, std::size_t count, const double* F, double* U, double* sigma,
                       double* V) {
  Lanes f[9], u[9], s[3], v[9];
  for (int k = 0; k < 9; ++k)
    for (int l = 0; l < kLanes; ++l)
      f[k][l] =
          static_cast<std::size_t>(l) < count ? F[9 * (i0 + l) + k] : (k % 4 == 0 ? 1.0 : 0.0);
  detail::svd3_generic<Lanes>(f, u, s, v);
  for (std::size_t l = 0; l < count; ++l) {
    for (int k = 0; k < 9; ++k) {
      U[9 * (i0 + l) + k] = u[k][l];
      V[9 * (i0 + l) + k] = v[k][l];
    }
    for (int k = 0; k < 3; ++k) sigma[3 * (i0 + l) + k] = s[k][l];
  }
}

template <int Dummy>
inline void batch(std::size_t n, const double* F, double* U, double* sigma, double* V) {
  for (std::size_t i = 0; i < n; i += kLanes)
    svd3_lanes<Dummy>(i, n - i < kLanes ? n - i : kLanes, F, U, sigma, V);
}

__attribute__((target("avx2"))) void batch_avx2(std::size_t n, const double* F, double* U,
                                                double* sigma, double* V) {
  batch<1>(n, F, U, sigma, V);
}

void batch_sse2(std::size_t n, const double* F, double* U, double* sigma, double* V) {
  batch<0>(n, F, U, sigma, V);
}

}  // namespace

void svd3_batch(std::size_t n, const double* F, double* U, double* sigma, double* V) {
  static const bool avx2 = __builtin_cpu_supports("avx2");
  if (avx2)
    batch_avx2(n, F, U, sigma, V);
  else
    batch_sse2(n, F, U, sigma, V);
}

}  // namespace gen4d::materials
