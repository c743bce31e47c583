//! The fused NeuralMTL pass (MLP, activation, energy, reverse pass), written once for a lane
//! type T and compiled by both compilers: T = double is one point (the CUDA kernel, one point
//! per thread), T = a vector of doubles is a group of points evaluated together (the CPU
//! kernel, NeuralMtl.cpp). A lane type provides + - * / with doubles and LaneOps<T>.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>

#include "materials/Hd.hpp"

//! Every function of the pass is forced inline, so that each instruction-set build of the CPU
//! kernel (NeuralMtl.cpp) and the CUDA kernel compile it whole, in their own instruction set.
#if defined(__CUDACC__)
#define GEN4D_KERNEL_INLINE __forceinline__
#elif defined(__GNUC__)
#define GEN4D_KERNEL_INLINE inline __attribute__((always_inline))
#else
#define GEN4D_KERNEL_INLINE inline
#endif

namespace gen4d::neural {

inline constexpr int kMaxWidth = 64;  //!< widest hidden layer the fused kernel accepts
inline constexpr int kMaxLayers = 6;  //!< most affine layers the fused kernel accepts
inline constexpr int kPad = 4;        //!< layer widths are padded to a multiple of this

//! A network in the kernel's layout, as raw pointers (host or device memory). Widths are
//! padded to kPad with zero weights and biases: a padded unit computes tanh(0) = 0 and feeds
//! nothing forward or back.
struct NetView {
  int layers = 0;
  int width[kMaxLayers + 1] = {};     //!< padded widths, width[0] = 4 (inputs)
  const double* W[kMaxLayers] = {};   //!< width[l+1] x width[l], row-major
  const double* Wt[kMaxLayers] = {};  //!< its transpose
  const double* b[kMaxLayers] = {};   //!< width[l+1]
  double m0[3] = {};                  //!< raw output at rest, subtracted by the activation
};

//! Per-lane-type helpers: a constant in every lane, abs, min with a constant, copysign onto a
//! non-negative value, and 2^n from a double whose low mantissa bits hold n (see tanh_lane).
template <class T>
struct LaneOps;

template <>
struct LaneOps<double> {
  GEN4D_HD GEN4D_KERNEL_INLINE static double splat(double c) { return c; }
  GEN4D_HD GEN4D_KERNEL_INLINE static double abs(double x) { return fabs(x); }
  GEN4D_HD GEN4D_KERNEL_INLINE static double min(double x, double c) { return x < c ? x : c; }
  GEN4D_HD GEN4D_KERNEL_INLINE static double copysign(double mag, double sgn) {
    return ::copysign(mag, sgn);
  }
  GEN4D_HD GEN4D_KERNEL_INLINE static double pow2(double t) {
#if defined(__CUDA_ARCH__)
    const unsigned long long bits = static_cast<unsigned long long>(__double_as_longlong(t));
    return __longlong_as_double(static_cast<long long>((bits << 52) + (1023ULL << 52)));
#else
    std::uint64_t bits;
    std::memcpy(&bits, &t, sizeof bits);
    bits = (bits << 52) + (std::uint64_t{1023} << 52);
    double out;
    std::memcpy(&out, &bits, sizeof out);
    return out;
#endif
  }
};

//! tanh to double precision (relative error below 5e-16, about 2 ulp, small arguments
//! included), branch-free so that lanes vectorise.
//! With s = min(|a|, 20) (tanh is 1 to double precision beyond): e^{2s} = 2^n e^r,
//! |r| <= ln2/2, and e^r = (E + O) / (E - O) by its [6/6] Pade approximant (E, O: its even and
//! odd parts; truncation < 1e-18). Then
//!   tanh(s) = (2^n (E+O) - (E-O)) / (2^n (E+O) + (E-O))
//!           = ((2^n - 1) E + (2^n + 1) O) / ((2^n + 1) E + (2^n - 1) O),
//! whose numerator has no cancellation (2 O at n = 0), so small arguments keep full relative
//! precision. One division per value.
template <class T>
GEN4D_HD GEN4D_KERNEL_INLINE T tanh_lane(const T& a) {
  using Ops = LaneOps<T>;
  constexpr double kShift = 6755399441055744.0;  // 1.5 * 2^52: adding it rounds to an integer
  constexpr double k2Log2e = 2.8853900817779268, kLn2Hi = 6.93147180369123816490e-01,
                   kLn2Lo = 1.90821492927058770002e-10;
  const T s = Ops::min(Ops::abs(a), 20.0);
  const T t = s * k2Log2e + kShift;  // n = round(2 s / ln2) in the low bits
  const T nf = t - kShift;
  const T r = (s * 2.0 - nf * kLn2Hi) - nf * kLn2Lo;
  const T r2 = r * r;
  // Pade [6/6] of e^r: N(r) / N(-r), N(r) = sum c_k r^k, c_k = (12-k)! 6! / (12! k! (6-k)!).
  const T E = ((r2 * (1.0 / 665280.0) + 1.0 / 792.0) * r2 + 5.0 / 44.0) * r2 + 1.0;
  const T O = ((r2 * (1.0 / 15840.0) + 1.0 / 66.0) * r2 + 0.5) * r;
  const T scale = Ops::pow2(t);
  const T sm = scale - 1.0, sp = scale + 1.0;
  return Ops::copysign((sm * E + sp * O) / (sp * E + sm * O), a);
}

//! y[j] = bias[j] + sum_{i < in} M[j * in + i] x[i] for j < out (out a multiple of kPad;
//! bias may be null), then y[j] = post(j, y[j]). Rows go in register blocks of Block (then
//! kPad) so that each x[i] loaded feeds a whole block of multiply-adds.
template <int Block, class T, class Post>
GEN4D_HD GEN4D_KERNEL_INLINE void dense(int in, int out, const double* M, const double* bias,
                                        const T* x, T* y, const Post& post) {
  int j0 = 0;
  for (; j0 + Block <= out; j0 += Block) {
    T acc[Block];
    for (int r = 0; r < Block; ++r) acc[r] = LaneOps<T>::splat(bias ? bias[j0 + r] : 0.0);
    for (int i = 0; i < in; ++i) {
      const T xi = x[i];
      for (int r = 0; r < Block; ++r) acc[r] += M[(j0 + r) * in + i] * xi;
    }
    for (int r = 0; r < Block; ++r) y[j0 + r] = post(j0 + r, acc[r]);
  }
  if constexpr (Block > kPad) {
    for (; j0 < out; j0 += kPad) {
      T acc[kPad];
      for (int r = 0; r < kPad; ++r) acc[r] = LaneOps<T>::splat(bias ? bias[j0 + r] : 0.0);
      for (int i = 0; i < in; ++i) {
        const T xi = x[i];
        for (int r = 0; r < kPad; ++r) acc[r] += M[(j0 + r) * in + i] * xi;
      }
      for (int r = 0; r < kPad; ++r) y[j0 + r] = post(j0 + r, acc[r]);
    }
  }
}

//! The steps after each dense layer: tanh (hidden layers), the activation's shift (output
//! layer), tanh' = 1 - h^2 (reverse pass), nothing.
struct PostTanh {
  template <class T>
  GEN4D_HD GEN4D_KERNEL_INLINE T operator()(int, const T& v) const {
    return tanh_lane(v);
  }
};
struct PostShift {
  const double* m0;
  template <class T>
  GEN4D_HD GEN4D_KERNEL_INLINE T operator()(int j, const T& v) const {
    return j < 3 ? v - m0[j] : v;
  }
};
template <class T>
struct PostTanhPrime {
  const T* h;
  GEN4D_HD GEN4D_KERNEL_INLINE T operator()(int i, const T& v) const {
    return v * (1.0 - h[i] * h[i]);
  }
};
struct PostNone {
  template <class T>
  GEN4D_HD GEN4D_KERNEL_INLINE T operator()(int, const T& v) const {
    return v;
  }
};

//! One lane group through the network. In: x[0..2] = sigma - 1 per lane. Out: n[0..2] the
//! neural strain; with Backward, grad = d psi / d sigma = J_n^T n for psi = |n|^2 / 2.
//! h: scratch of (kMaxLayers + 1) x S lane values, g: 2 x S, S >= every padded width.
template <int Block, bool Backward, class T, int S>
GEN4D_HD GEN4D_KERNEL_INLINE void neural_pass(const NetView& net, const T x[3], T (*h)[S],
                                              T (*g)[S], T n[3], T grad[3]) {
  const int last = net.layers - 1;
  for (int a = 0; a < 3; ++a) h[0][a] = x[a];
  h[0][3] = LaneOps<T>::splat(0.0);
  for (int l = 0; l < last; ++l)
    dense<Block>(net.width[l], net.width[l + 1], net.W[l], net.b[l], h[l], h[l + 1], PostTanh{});
  // The activation subtracts the raw output at rest, so n vanishes at rest exactly.
  dense<Block>(net.width[last], net.width[last + 1], net.W[last], net.b[last], h[last], h[last + 1],
               PostShift{net.m0});
  for (int a = 0; a < 3; ++a) n[a] = h[last + 1][a];
  if constexpr (Backward) {
    // Reverse pass of psi = |n|^2 / 2: g starts at n and goes back through each layer:
    // g_in = W^T g_out, times tanh' = 1 - h^2 below the last layer.
    for (int a = 0; a < net.width[last + 1]; ++a) g[0][a] = h[last + 1][a];
    int cur = 0;
    for (int l = last; l > 0; --l) {
      dense<Block>(net.width[l + 1], net.width[l], net.Wt[l], nullptr, g[cur], g[1 - cur],
                   PostTanhPrime<T>{h[l]});
      cur = 1 - cur;
    }
    dense<kPad>(net.width[1], net.width[0], net.Wt[0], nullptr, g[cur], g[1 - cur], PostNone{});
    for (int a = 0; a < 3; ++a) grad[a] = g[1 - cur][a];
  }
}

//! The pointwise kernel of the CUDA back end: one point per index; sigma, strain and dpsi hold
//! 3 values per point, psi 1. strain and psi may be null; dpsi is written iff Backward.
//! S: scratch row length, at least the network's widest padded layer (the scratch is the
//! thread's local memory, so the launcher picks the smallest that fits).
template <bool Backward, int S = kMaxWidth>
struct NeuralPointKernel {
  NetView net;
  const double* sigma = nullptr;
  double* psi = nullptr;
  double* dpsi = nullptr;
  double* strain = nullptr;

  GEN4D_HD void operator()(long i) const {
    double h[kMaxLayers + 1][S], g[2][S];
    const double x[3] = {sigma[3 * i] - 1.0, sigma[3 * i + 1] - 1.0, sigma[3 * i + 2] - 1.0};
    double n[3], d[3];
    neural_pass<8, Backward>(net, x, h, g, n, d);
    if (strain)
      for (int a = 0; a < 3; ++a) strain[3 * i + a] = n[a];
    if (psi) psi[i] = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]) * 0.5;
    if constexpr (Backward)
      for (int a = 0; a < 3; ++a) dpsi[3 * i + a] = d[a];
  }
};

}  // namespace gen4d::neural
