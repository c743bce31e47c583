// CPU port of the forward pass of the 3DGS rasterizer (graphdeco-inria diff-gaussian-
// rasterization: preprocessCUDA, computeCov2D, computeColorFromSH, renderCUDA), single
// precision throughout as there. The per-splat projection and the per-pixel step are the
// GEN4D_HD functions of RenderDetail.hpp, which Render.cu runs on a GPU.
#include "gaussians/Render.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>

#if defined(_OPENMP)
#include <omp.h>
#endif
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

#include "core/Device.hpp"
#include "core/Error.hpp"
#include "core/ParallelFor.hpp"
#include "gaussians/RenderDetail.hpp"
#include "gaussians/SphericalHarmonics.hpp"
#include "io/PngPreview.hpp"

namespace gen4d::gaussians {
namespace detail {

namespace {

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

SplatPointers pointers(const SplatFrame& s) {
  const std::size_t n = s.size();
  if (s.sh_degree < 0 || s.sh_degree > kMaxShDegree)
    throw std::logic_error("render: SplatFrame SH degree out of range");
  const std::size_t k = static_cast<std::size_t>(sh_coefficients(s.sh_degree));
  if (s.position.size() != 3 * n || s.covariance.size() != 6 * n || s.sh.size() != 3 * k * n ||
      !(s.sh_rotation.empty() || s.sh_rotation.size() == 9 * n))
    throw std::logic_error("render: SplatFrame arrays do not match its size and SH degree");
  SplatPointers p;
  p.position = s.position.data();
  p.covariance = s.covariance.data();
  p.opacity = s.opacity.data();
  p.sh = s.sh.data();
  p.sh_rotation = s.sh_rotation.empty() ? nullptr : s.sh_rotation.data();
  p.sh_degree = s.sh_degree;
  return p;
}

View::View(const Camera& c) {
  if (c.width < 1 || c.height < 1 || c.width > 65535 * kTile || c.height > 65535 * kTile)
    throw InputError("render: image size " + std::to_string(c.width) + "x" +
                     std::to_string(c.height) + " is out of range");
  if (!(c.fx > 0) || !(c.fy > 0) || !std::isfinite(c.fx) || !std::isfinite(c.fy))
    throw InputError("render: camera focal lengths must be positive");
  width = c.width;
  height = c.height;
  grid_x = (width + kTile - 1) / kTile;
  grid_y = (height + kTile - 1) / kTile;
  const auto& R = c.rotation;  // camera -> world, row-major
  for (int i = 0; i < 3; ++i) {
    double t = 0;
    for (int j = 0; j < 3; ++j) {
      view[3 * i + j] = static_cast<float>(R[3 * j + i]);
      t -= R[3 * j + i] * c.position[j];
    }
    trans[i] = static_cast<float>(t);
    campos[i] = static_cast<float>(c.position[i]);
  }
  fx = static_cast<float>(c.fx);
  fy = static_cast<float>(c.fy);
  tan_fovx = static_cast<float>(width / (2.0 * c.fx));
  tan_fovy = static_cast<float>(height / (2.0 * c.fy));
  cx = 0.5f * static_cast<float>(width - 1);  // ndc2Pix: principal point at (W - 1) / 2
  cy = 0.5f * static_cast<float>(height - 1);
}

void preprocess(const SplatFrame& s, const View& v, std::vector<Projected>& out) {
  const SplatPointers sp = pointers(s);
  const std::size_t n = s.size();
  // A fixed number of chunks (not of threads), each projected into its own part of `out` and
  // then moved down behind the previous ones, in order.
  const std::size_t chunks = std::min<std::size_t>(64, std::max<std::size_t>(1, n / 4096));
  const std::size_t base = out.size();
  out.resize(base + n);
  Projected* dst = out.data() + base;
  std::vector<std::size_t> kept(chunks);
  exec::parallel_for_dynamic(static_cast<long>(chunks), [&](long ci) {
    const std::size_t lo = n * static_cast<std::size_t>(ci) / chunks;
    const std::size_t hi = n * static_cast<std::size_t>(ci + 1) / chunks;
    std::size_t m = lo;
    for (std::size_t i = lo; i < hi; ++i)
      if (project(sp, v, static_cast<long>(i), dst[m])) ++m;
    kept[static_cast<std::size_t>(ci)] = m - lo;
  });
  std::size_t end = 0;
  for (std::size_t ci = 0; ci < chunks; ++ci) {
    const std::size_t lo = n * ci / chunks;
    if (end != lo) std::memmove(dst + end, dst + lo, kept[ci] * sizeof(Projected));
    end += kept[ci];
  }
  out.resize(base + end);
}

namespace {

//! Sorts keys (depth bits << 32 | index) by their upper half, stably: LSD radix, 8 bits a
//! pass, passes whose digit is the same for every key skipped.
void radix_sort_upper(std::vector<std::uint64_t>& keys) {
  const std::size_t n = keys.size();
  if (n < 2) return;
  std::vector<std::size_t> count(4 * 256, 0);
  for (const std::uint64_t k : keys)
    for (int d = 0; d < 4; ++d) ++count[256 * d + ((k >> (32 + 8 * d)) & 255)];
  static thread_local std::vector<std::uint64_t> tmp_buffer;
  std::vector<std::uint64_t>& tmp = tmp_buffer;
  tmp.resize(n);
  for (int d = 0; d < 4; ++d) {
    std::size_t* c = &count[256 * static_cast<std::size_t>(d)];
    const int shift = 32 + 8 * d;
    if (c[(keys[0] >> shift) & 255] == n) continue;
    std::size_t sum = 0;
    for (int b = 0; b < 256; ++b) {
      const std::size_t x = c[b];
      c[b] = sum;
      sum += x;
    }
    for (const std::uint64_t k : keys) tmp[c[(k >> shift) & 255]++] = k;
    keys.swap(tmp);
  }
}

}  // namespace

void bin_tiles(std::vector<Projected>& splats, const View& v, int row0, int row1,
               std::vector<std::uint32_t>& offsets, std::vector<std::uint32_t>& entries,
               bool legacy) {
  // Sort (depth bits, index) pairs (depths are positive: their bits order like the values),
  // breaking ties with the full canonical comparison.
  const std::size_t n = splats.size();
  if (n > 0xffffffffu) throw RuntimeError("render: more than 2^32 visible splats");
  // Buffers kept between renders on this thread: no fresh memory to fault in every frame.
  // (Referenced through locals: a lambda run by another thread would see that thread's own.)
  static thread_local std::vector<std::uint64_t> keys_buffer;
  std::vector<std::uint64_t>& keys = keys_buffer;
  keys.resize(n);
  for (std::size_t i = 0; i < n; ++i)
    keys[i] = (static_cast<std::uint64_t>(float_bits(splats[i].depth)) << 32) | i;
  auto canonical = [&](std::uint64_t a, std::uint64_t b) {
    if ((a >> 32) != (b >> 32)) return a < b;
    return before(splats[a & 0xffffffffu], splats[b & 0xffffffffu]);
  };
  // The splats' tile rectangles, in canonical order.
  struct Rect {
    std::uint16_t x0, y0, x1, y1;
  };
  static thread_local std::vector<Rect> rect_buffer;
  static thread_local std::vector<std::uint32_t> order_buffer;
  std::vector<Rect>& rect = rect_buffer;
  std::vector<std::uint32_t>& order = order_buffer;  // the splat at each canonical position
  rect.resize(n);
  order.resize(n);
  if (legacy) {
    // The comparison sort, then the splats permuted into that order.
    std::sort(keys.begin(), keys.end(), canonical);
    std::vector<Projected> sorted(n);
    for (std::size_t i = 0; i < n; ++i) sorted[i] = splats[keys[i] & 0xffffffffu];
    splats.swap(sorted);
    for (std::size_t i = 0; i < n; ++i) order[i] = static_cast<std::uint32_t>(i);
  } else {
    radix_sort_upper(keys);
    for (std::size_t i = 0; i < n;) {  // runs of equal depth: the canonical order
      std::size_t j = i + 1;
      while (j < n && (keys[j] >> 32) == (keys[i] >> 32)) ++j;
      if (j - i > 1)
        std::sort(keys.begin() + static_cast<long>(i), keys.begin() + static_cast<long>(j),
                  canonical);
      i = j;
    }
    for (std::size_t i = 0; i < n; ++i) order[i] = static_cast<std::uint32_t>(keys[i]);
  }
  exec::parallel_for(static_cast<long>(n), [&](long i) {
    const Projected& g = splats[order[static_cast<std::size_t>(i)]];
    rect[static_cast<std::size_t>(i)] = {g.x0, g.y0, g.x1, g.y1};
  });

  // Tile lists: blocks of the canonical order counted and filled in parallel, each tile's
  // entries in canonical order whatever the blocks.
  const int gx = v.grid_x;
  const std::size_t tiles = static_cast<std::size_t>(row1 - row0) * static_cast<std::size_t>(gx);
  const std::size_t blocks = tiles > (std::size_t{1} << 20)
                                 ? 1
                                 : std::min<std::size_t>(16, std::max<std::size_t>(1, n / 8192));
  static thread_local std::vector<std::uint32_t> start_buffer;
  std::vector<std::uint32_t>& start = start_buffer;
  start.assign(blocks * tiles, 0);
  auto each_tile = [&](const Rect& g, auto&& f) {
    const int y0 = std::max<int>(g.y0, row0), y1 = std::min<int>(g.y1, row1);
    for (int ty = y0; ty < y1; ++ty)
      for (int tx = g.x0; tx < g.x1; ++tx) f(static_cast<std::size_t>(ty - row0) * gx + tx);
  };
  exec::parallel_for_dynamic(static_cast<long>(blocks), [&](long b) {
    std::uint32_t* count = &start[static_cast<std::size_t>(b) * tiles];
    for (std::size_t i = n * b / blocks; i < n * (b + 1) / blocks; ++i)
      each_tile(rect[i], [&](std::size_t t) { ++count[t]; });
  });
  offsets.assign(tiles + 1, 0);
  std::uint64_t sum = 0;
  for (std::size_t t = 0; t < tiles; ++t) {
    offsets[t] = static_cast<std::uint32_t>(sum);
    for (std::size_t b = 0; b < blocks; ++b) {
      const std::uint32_t c = start[b * tiles + t];
      start[b * tiles + t] = static_cast<std::uint32_t>(sum);
      sum += c;
    }
    if (sum > 0xffffffffu) throw RuntimeError("render: too many tile entries");
  }
  offsets[tiles] = static_cast<std::uint32_t>(sum);
  entries.resize(sum);
  exec::parallel_for_dynamic(static_cast<long>(blocks), [&](long b) {
    std::uint32_t* fill = &start[static_cast<std::size_t>(b) * tiles];
    for (std::size_t i = n * b / blocks; i < n * (b + 1) / blocks; ++i)
      each_tile(rect[i], [&](std::size_t t) { entries[fill[t]++] = order[i]; });
  });
}

namespace {

//! The previous blend: every pixel walks its tile's list (gathered as structure of arrays).
struct TileData {
  std::vector<float> x, y, c0, c1, c2, o, r, g, b, cut;
  void resize(std::size_t n) {
    for (auto* v : {&x, &y, &c0, &c1, &c2, &o, &r, &g, &b, &cut}) v->resize(n);
  }
};

inline void blend_pixel(const TileData& t, std::size_t count, float px, float py, const float bg[3],
                        float* out) {
  float T = 1.0f;
  float C[3] = {0, 0, 0};
  for (std::size_t j = 0; j < count; ++j) {
    const float dx = t.x[j] - px, dy = t.y[j] - py;
    const float power = -0.5f * (t.c0[j] * dx * dx + t.c2[j] * dy * dy) - t.c1[j] * dx * dy;
    if (power > 0.0f) continue;
    if (power < t.cut[j]) continue;
    const float alpha = std::min(0.99f, t.o[j] * std::exp(power));
    if (alpha < 1.0f / 255.0f) continue;
    const float test_T = T * (1 - alpha);
    if (test_T < 0.0001f) break;
    C[0] += t.r[j] * alpha * T;
    C[1] += t.g[j] * alpha * T;
    C[2] += t.b[j] * alpha * T;
    T = test_T;
  }
  for (int ch = 0; ch < 3; ++ch) out[ch] = C[ch] + T * bg[ch];
}

void load(TileData& t, std::size_t j, const Projected& g) {
  t.x[j] = g.x;
  t.y[j] = g.y;
  t.c0[j] = g.conic[0];
  t.c1[j] = g.conic[1];
  t.c2[j] = g.conic[2];
  t.o[j] = g.opacity;
  t.r[j] = g.rgb[0];
  t.g[j] = g.rgb[1];
  t.b[j] = g.rgb[2];
  t.cut[j] = power_cut(g.opacity);
}

void blend_tile_legacy(const Projected* splats, const std::uint32_t* list, std::size_t count,
                       const View& v, int tx, int ty, int row0, const float bg[3], float* rgb) {
  static thread_local TileData t;
  if (t.x.size() < count) t.resize(count);
  for (std::size_t j = 0; j < count; ++j) load(t, j, splats[list[j]]);
  const int x_end = std::min((tx + 1) * kTile, v.width);
  const int y_end = std::min((ty + 1) * kTile, v.height);
  for (int py = ty * kTile; py < y_end; ++py)
    for (int px = tx * kTile; px < x_end; ++px) {
      float* out = rgb + (static_cast<std::size_t>(py - row0 * kTile) * v.width + px) * 3;
      blend_pixel(t, count, static_cast<float>(px), static_cast<float>(py), bg, out);
    }
}

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wpsabi"
#endif
#if defined(__x86_64__) && defined(__GNUC__)
#define GEN4D_RENDER_AVX2 1
#define GEN4D_RENDER_INLINE inline __attribute__((always_inline))
#else
#define GEN4D_RENDER_AVX2 0
#define GEN4D_RENDER_INLINE inline
#endif

//! Eight pixels of a tile row (GCC/Clang vector extensions: one AVX register, or two SSE ones).
typedef float F8 __attribute__((vector_size(32)));
typedef std::int32_t I8 __attribute__((vector_size(32)));

//! Bit l set where lane l of `m` (all ones or zero) is set.
GEN4D_RENDER_INLINE unsigned lane_bits(const I8& m) {
  typedef std::int32_t I4 __attribute__((vector_size(16)));
  const I8 weight = {1, 2, 4, 8, 16, 32, 64, 128};
  const I8 t = m & weight;
  I4 x = __builtin_shufflevector(t, t, 0, 1, 2, 3) | __builtin_shufflevector(t, t, 4, 5, 6, 7);
  x |= __builtin_shufflevector(x, x, 2, 3, 0, 1);
  x |= __builtin_shufflevector(x, x, 1, 0, 3, 2);
  return static_cast<unsigned>(x[0]);
}

#if GEN4D_RENDER_AVX2
//! std::exp (expf) of eight floats x (those of the halves that `lanes` has bits in), bit for bit as
//! the C library computes it on x86-64 CPUs with FMA (glibc's __expf_fma, the algorithm of ARM's
//! optimized-routines): x N / ln 2 = k + r (N = 32), exp(x) = 2^(k / N) 2^(r / N), the first from a
//! table, the second a cubic, in double with the same fused multiply-adds, rounded to float once.
//! exp_vector_matches() checks it against the library before it is used.
alignas(32) constexpr std::uint64_t kExp2Table[32] = {
    0x3ff0000000000000, 0x3fefd9b0d3158574, 0x3fefb5586cf9890f, 0x3fef9301d0125b51,
    0x3fef72b83c7d517b, 0x3fef54873168b9aa, 0x3fef387a6e756238, 0x3fef1e9df51fdee1,
    0x3fef06fe0a31b715, 0x3feef1a7373aa9cb, 0x3feedea64c123422, 0x3feece086061892d,
    0x3feebfdad5362a27, 0x3feeb42b569d4f82, 0x3feeab07dd485429, 0x3feea47eb03a5585,
    0x3feea09e667f3bcd, 0x3fee9f75e8ec5f74, 0x3feea11473eb0187, 0x3feea589994cce13,
    0x3feeace5422aa0db, 0x3feeb737b0cdc5e5, 0x3feec49182a3f090, 0x3feed503b23e255d,
    0x3feee89f995ad3ad, 0x3feeff76f2fb5e47, 0x3fef199bdd85529c, 0x3fef3720dcef9069,
    0x3fef5818dcfba487, 0x3fef7c97337b9b5f, 0x3fefa4afa2a490da, 0x3fefd0765b6e4540};

double from_bits(std::uint64_t u) {
  double d;
  std::memcpy(&d, &u, sizeof d);
  return d;
}
//! N / ln 2, the rounding shift 1.5 2^52, and the cubic's coefficients (scaled by 1/N^k).
const double kExpConst[5] = {from_bits(0x40471547652b82feULL), from_bits(0x4338000000000000ULL),
                             from_bits(0x3ebc6af84b912394ULL), from_bits(0x3f2ebfce50fac4f3ULL),
                             from_bits(0x3f962e42ff0c52d6ULL)};

__attribute__((target("avx2,fma"))) void exp8(const float* x, float* out, unsigned lanes) {
  const __m256d inv_ln2_n = _mm256_set1_pd(kExpConst[0]), shift = _mm256_set1_pd(kExpConst[1]);
  const __m256d c0 = _mm256_set1_pd(kExpConst[2]), c1 = _mm256_set1_pd(kExpConst[3]);
  const __m256d c2 = _mm256_set1_pd(kExpConst[4]), one = _mm256_set1_pd(1.0);
  const __m256 xf = _mm256_loadu_ps(x);
  __m128 half[2] = {_mm_setzero_ps(), _mm_setzero_ps()};
  for (int h = 0; h < 2; ++h) {
    if (((lanes >> (4 * h)) & 15) == 0) continue;  // no lane of this half is wanted
    const __m256d xd =
        _mm256_cvtps_pd(h == 0 ? _mm256_castps256_ps128(xf) : _mm256_extractf128_ps(xf, 1));
    const __m256d z = _mm256_fmadd_pd(inv_ln2_n, xd, shift);
    const __m256i ki = _mm256_castpd_si256(z);
    const __m256d kd = _mm256_sub_pd(z, shift);
    const __m256d r = _mm256_fmsub_pd(inv_ln2_n, xd, kd);
    alignas(32) std::uint64_t k[4];
    _mm256_store_si256(reinterpret_cast<__m256i*>(k), ki);
    __m256i t = _mm256_set_epi64x(static_cast<long long>(kExp2Table[k[3] & 31]),
                                  static_cast<long long>(kExp2Table[k[2] & 31]),
                                  static_cast<long long>(kExp2Table[k[1] & 31]),
                                  static_cast<long long>(kExp2Table[k[0] & 31]));
    t = _mm256_add_epi64(t, _mm256_slli_epi64(ki, 47));
    const __m256d p = _mm256_fmadd_pd(r, c0, c1);
    const __m256d r2 = _mm256_mul_pd(r, r);
    const __m256d q = _mm256_fmadd_pd(r, c2, one);
    const __m256d y = _mm256_mul_pd(_mm256_fmadd_pd(p, r2, q), _mm256_castsi256_pd(t));
    half[h] = _mm256_cvtpd_ps(y);
  }
  _mm256_storeu_ps(out, _mm256_set_m128(half[1], half[0]));
  // |x| >= 88, inf, NaN: the library's own path.
  const __m256i top =
      _mm256_and_si256(_mm256_srli_epi32(_mm256_castps_si256(xf), 20), _mm256_set1_epi32(0x7ff));
  if (_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(top, _mm256_set1_epi32(0x42a)))))
    for (int l = 0; l < 8; ++l) {
      std::uint32_t u;
      std::memcpy(&u, &x[l], sizeof u);
      if (((u >> 20) & 0x7ff) > 0x42a) out[l] = std::exp(x[l]);
    }
}

//! Whether exp8 gives std::exp's floats here (this CPU has FMA and the C library computes expf
//! as above): every float -k/4096 down to -6, powers of two down to 2^-149, random ones in
//! [-100, 0].
bool exp_vector_matches() {
  __builtin_cpu_init();
  if (!__builtin_cpu_supports("avx2") || !__builtin_cpu_supports("fma")) return false;
  std::vector<float> x;
  for (int k = 0; k <= 6 * 4096; ++k) x.push_back(-static_cast<float>(k) / 4096.0f);
  for (int e = 0; e < 150; ++e) x.push_back(-std::ldexp(1.0f, -e));
  std::uint32_t state = 12345;
  for (int i = 0; i < 65536; ++i) {
    state = state * 1664525u + 1013904223u;
    x.push_back(-100.0f * static_cast<float>(state >> 8) / 16777216.0f);
  }
  x.resize((x.size() + 7) / 8 * 8, 0.0f);
  float out[8];
  for (std::size_t i = 0; i < x.size(); i += 8) {
    exp8(&x[i], out, 255);
    for (int l = 0; l < 8; ++l)
      if (float_bits(out[l]) != float_bits(std::exp(x[i + l]))) return false;
  }
  return true;
}
#endif

//! One tile, splat by splat (the order of renderCUDA's shared-memory batches): the tile's
//! pixels keep their C and T, each splat visits only the pixels of its ellipse's bounding box,
//! and the tile ends when every pixel is finished. A splat's powers are computed eight pixels
//! of a row at a time (splat_power's float operations in its order), the pixels whose power
//! lies in [alpha_cut, 0] listed, then blended one by one with blend_power. Each pixel thus
//! sees the same blend_power calls, in the same order, as when it walks the list alone with
//! blend_step (less some below alpha_cut, an exact skip): the image is the same bit for bit.
//!
//! The box: the conic's ellipse c0 dx^2 + 2 c1 dx dy + c2 dy^2 <= L with L = 2 (-cut + margin)
//! spans |dx| <= sqrt(L c2 / det), |dy| <= sqrt(L c0 / det) (det = c0 c2 - c1^2), widened by a
//! pixel (the rounding of dx and dy). The margin bounds the float error of the power, 4 ulp of
//! 0.5 (c0 dx^2 + c2 dy^2) + |c1 dx dy| at most (taken over the tile, 8 times over).
template <bool kVectorExp>
GEN4D_RENDER_INLINE void blend_tile_body(const Projected* splats, const float* splat_cuts,
                                         const std::uint32_t* list, std::size_t count,
                                         const View& v, int tx, int ty, int row0, const float bg[3],
                                         float* rgb) {
  constexpr int kPix = kTile * kTile;
  // The tile's splats gathered a batch at a time: the loads are independent, so their cache
  // misses overlap, and a tile finished early gathers few more than it uses.
  constexpr std::size_t kBatch = 64;
  Projected local[kBatch];
  float cuts[kBatch];

  const int x_begin = tx * kTile, y_begin = ty * kTile;
  const int w = std::min(kTile, v.width - x_begin), h = std::min(kTile, v.height - y_begin);
  alignas(32) std::int32_t live[kPix];  // -1 while the pixel takes splats, 0 once finished
  alignas(32) float T[kPix], Cr[kPix], Cg[kPix], Cb[kPix];
  int row_live[kTile];
  for (int k = 0; k < kPix; ++k) {
    T[k] = 1.0f;
    Cr[k] = Cg[k] = Cb[k] = 0.0f;
    live[k] = (k / kTile < h && k % kTile < w) ? -1 : 0;
  }
  for (int r = 0; r < kTile; ++r) row_live[r] = r < h ? w : 0;
  int left = w * h;
  const double x_lo = x_begin, x_hi = x_begin + w - 1, y_lo = y_begin, y_hi = y_begin + h - 1;
  constexpr double kFar = 4194304.0;  // 2^22: beyond, a pixel's dx may round by a pixel or more
  auto to_int = [](double val, double lo, double hi) {
    return static_cast<int>(std::min(hi, std::max(lo, val)));  // NaN -> lo
  };
  auto load = [](const auto* p, auto& x) { std::memcpy(&x, p, sizeof x); };
  auto store = [](auto* p, const auto& x) { std::memcpy(p, &x, sizeof x); };
  const F8 lane = {0, 1, 2, 3, 4, 5, 6, 7};
  for (std::size_t j = 0; j < count && left > 0; ++j) {
    if (j % kBatch == 0)
      for (std::size_t b = j; b < std::min(count, j + kBatch); ++b) {
        local[b - j] = splats[list[b]];
        cuts[b - j] = splat_cuts[list[b]];
        if (b + kBatch < count) __builtin_prefetch(&splats[list[b + kBatch]]);
      }
    const Projected& g = local[j % kBatch];
    const float cut = cuts[j % kBatch];
    if (!(cut <= 0.0f)) continue;  // no power passes (powers above 0 are skipped too)
    const double c0 = g.conic[0], c1 = g.conic[1], c2 = g.conic[2];
    const double det = c0 * c2 - c1 * c1;  // exact products of floats, one rounding
    int ya = y_begin, yb = y_begin + h - 1, xa = x_begin, xb = x_begin + w - 1;
    if (cut > -std::numeric_limits<float>::infinity() && c0 > 0 && c2 > 0 && det > 0 &&
        std::fabs(g.x) < kFar && std::fabs(g.y) < kFar) {
      const double mx = std::max(std::fabs(g.x - x_lo), std::fabs(g.x - x_hi));
      const double my = std::max(std::fabs(g.y - y_lo), std::fabs(g.y - y_hi));
      const double s_max = 0.5 * (c0 * mx * mx + c2 * my * my) + std::fabs(c1) * mx * my;
      const double L = 2.0 * (-static_cast<double>(cut) + 2e-6 * s_max + 1e-5);
      const double ex = std::sqrt(L * c2 / det) + 1.0, ey = std::sqrt(L * c0 / det) + 1.0;
      if (std::isfinite(ex) && std::isfinite(ey)) {  // else the whole tile
        xa = to_int(std::ceil(g.x - ex), x_lo, x_hi + 1);
        xb = to_int(std::floor(g.x + ex), x_lo - 1, x_hi);
        ya = to_int(std::ceil(g.y - ey), y_lo, y_hi + 1);
        yb = to_int(std::floor(g.y + ey), y_lo - 1, y_hi);
      }
    }
    if (xa > xb) continue;
    const int col_a = xa - x_begin, col_b = xb - x_begin;
    const int block_a = col_a & ~7, block_b = col_b & ~7;
    const I8 in_a = (lane >= static_cast<float>(col_a - block_a)) &
                    (lane <= static_cast<float>(col_b - block_a));
    const I8 in_b = lane <= static_cast<float>(col_b - block_b);  // when block_b > block_a
    const float c0f = g.conic[0], c1f = g.conic[1], c2f = g.conic[2];
    for (int py = ya; py <= yb; ++py) {
      const int r = py - y_begin;
      if (row_live[r] == 0) continue;
      const float dy = g.y - static_cast<float>(py);
      const float dyy = c2f * dy * dy;
      for (int col0 = block_a; col0 <= block_b; col0 += 8) {
        const int k0 = r * kTile + col0;
        I8 lv;
        load(&live[k0], lv);
        // splat_power and blend_power, eight lanes.
        const F8 dx = g.x - (static_cast<float>(x_begin + col0) + lane);
        const F8 power = -0.5f * (c0f * dx * dx + dyy) - c1f * dx * dy;
        const I8 pass = lv & (col0 == block_a ? in_a : in_b) & (power <= 0.0f) & (power >= cut);
        unsigned bits = lane_bits(pass);
        if (bits == 0) continue;
        F8 e = {0, 0, 0, 0, 0, 0, 0, 0};
        if constexpr (kVectorExp) {
#if GEN4D_RENDER_AVX2
          alignas(32) float in[8], out[8];
          store(in, pass ? power : F8{});
          exp8(in, out, bits);
          load(out, e);
#endif
        } else {
          while (bits) {
            const int l = __builtin_ctz(bits);
            bits &= bits - 1;
            e[l] = expf(power[l]);
          }
        }
        const F8 oe = g.opacity * e;
        const F8 alpha = oe < 0.99f ? oe : F8{} + 0.99f;  // hd_min(0.99f, oe)
        F8 t;
        load(&T[k0], t);
        const F8 test_t = t * (1.0f - alpha);
        const I8 use = pass & ~(alpha < 1.0f / 255.0f);
        const I8 stop = use & (test_t < 0.0001f);
        const I8 add = use & ~stop;
        {
          F8 cr, cg, cb;
          load(&Cr[k0], cr);
          load(&Cg[k0], cg);
          load(&Cb[k0], cb);
          store(&Cr[k0], add ? cr + g.rgb[0] * alpha * t : cr);
          store(&Cg[k0], add ? cg + g.rgb[1] * alpha * t : cg);
          store(&Cb[k0], add ? cb + g.rgb[2] * alpha * t : cb);
          store(&T[k0], add ? test_t : t);
        }
        if (const unsigned done = lane_bits(stop)) {
          store(&live[k0], lv & ~stop);
          const int n = __builtin_popcount(done);
          row_live[r] -= n;
          left -= n;
        }
      }
    }
  }
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      const int k = r * kTile + c;
      float* out =
          rgb + (static_cast<std::size_t>(y_begin + r - row0 * kTile) * v.width + x_begin + c) * 3;
      out[0] = Cr[k] + T[k] * bg[0];
      out[1] = Cg[k] + T[k] * bg[1];
      out[2] = Cb[k] + T[k] * bg[2];
    }
}

using BlendTile = void (*)(const Projected*, const float*, const std::uint32_t*, std::size_t,
                           const View&, int, int, int, const float*, float*);

void blend_tile_baseline(const Projected* splats, const float* cuts, const std::uint32_t* list,
                         std::size_t count, const View& v, int tx, int ty, int row0,
                         const float* bg, float* rgb) {
  blend_tile_body<false>(splats, cuts, list, count, v, tx, ty, row0, bg, rgb);
}

#if GEN4D_RENDER_AVX2
// AVX2 without FMA: no multiply-add can be contracted, so it rounds as the baseline does.
__attribute__((target("avx2"))) void blend_tile_avx2(const Projected* splats, const float* cuts,
                                                     const std::uint32_t* list, std::size_t count,
                                                     const View& v, int tx, int ty, int row0,
                                                     const float* bg, float* rgb) {
  blend_tile_body<false>(splats, cuts, list, count, v, tx, ty, row0, bg, rgb);
}
__attribute__((target("avx2"))) void blend_tile_avx2_exp8(
    const Projected* splats, const float* cuts, const std::uint32_t* list, std::size_t count,
    const View& v, int tx, int ty, int row0, const float* bg, float* rgb) {
  blend_tile_body<true>(splats, cuts, list, count, v, tx, ty, row0, bg, rgb);
}
#endif

//! The tile blend for this CPU: AVX2 where it has it, with exp8 where that matches std::exp.
BlendTile blend_tile_for_cpu() {
#if GEN4D_RENDER_AVX2
  if (exp_vector_matches()) return blend_tile_avx2_exp8;
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx2")) return blend_tile_avx2;
#endif
  return blend_tile_baseline;
}

}  // namespace

void blend_tiles(const std::vector<Projected>& splats, const View& v, int row0, int row1,
                 const std::vector<std::uint32_t>& offsets,
                 const std::vector<std::uint32_t>& entries, const RenderOptions& options,
                 float* rgb) {
  const int gx = v.grid_x;
  const long tiles = static_cast<long>(row1 - row0) * gx;
  const float bg[3] = {options.background[0], options.background[1], options.background[2]};
  if (options.legacy) {
    exec::parallel_for_dynamic(tiles, [&](long tile) {
      const int ty = row0 + static_cast<int>(tile / gx), tx = static_cast<int>(tile % gx);
      const std::size_t lo = offsets[static_cast<std::size_t>(tile)];
      const std::size_t hi = offsets[static_cast<std::size_t>(tile) + 1];
      blend_tile_legacy(splats.data(), entries.data() + lo, hi - lo, v, tx, ty, row0, bg, rgb);
    });
    return;
  }
  static const BlendTile blend_tile = blend_tile_for_cpu();
  static thread_local std::vector<float> cuts_buffer;  // referenced through a local, see bin_tiles
  std::vector<float>& cuts = cuts_buffer;
  cuts.resize(splats.size());
  exec::parallel_for(static_cast<long>(splats.size()), [&](long i) {
    cuts[static_cast<std::size_t>(i)] = alpha_cut(splats[static_cast<std::size_t>(i)].opacity);
  });
  exec::parallel_for_dynamic(tiles, [&](long tile) {
    const int ty = row0 + static_cast<int>(tile / gx), tx = static_cast<int>(tile % gx);
    const std::size_t lo = offsets[static_cast<std::size_t>(tile)];
    const std::size_t hi = offsets[static_cast<std::size_t>(tile) + 1];
    blend_tile(splats.data(), cuts.data(), entries.data() + lo, hi - lo, v, tx, ty, row0, bg, rgb);
  });
}

ThreadScope::ThreadScope(int threads) {
#if defined(_OPENMP)
  if (threads > 0) {
    saved_ = omp_get_max_threads();
    omp_set_num_threads(threads);
  }
#else
  (void)threads;
#endif
}

ThreadScope::~ThreadScope() {
#if defined(_OPENMP)
  if (saved_ > 0) omp_set_num_threads(saved_);
#endif
}

bool on_device(const RenderOptions& options) {
  return options.device && !options.legacy && exec::use_device();
}

}  // namespace detail

using detail::Projected;

Image render(const SplatFrame& splats, const Camera& camera, const RenderOptions& options) {
  const detail::View view(camera);
  const detail::ThreadScope threads(options.threads);
  RenderStats local;
  RenderStats& st = options.stats ? *options.stats : local;
#if defined(GEN4D_CUDA)
  if (detail::on_device(options)) {
    detail::pointers(splats);  // size checks
    detail::DeviceRenderer& gpu = detail::device_renderer();
    const double t0 = detail::now();
    gpu.upload(splats);
    st.transfer += detail::now() - t0;
    return gpu.render(view, options);
  }
#endif
  double t0 = detail::now();
  // Buffers kept between renders on this thread: no fresh memory to fault in every frame.
  static thread_local std::vector<Projected> projected;
  static thread_local std::vector<std::uint32_t> offsets, entries;
  projected.clear();
  detail::preprocess(splats, view, projected);
  double t1 = detail::now();
  st.preprocess += t1 - t0;
  st.visible += projected.size();
  detail::bin_tiles(projected, view, 0, view.grid_y, offsets, entries, options.legacy);
  double t2 = detail::now();
  st.sort += t2 - t1;
  st.tile_entries += entries.size();
  Image img;
  img.width = view.width;
  img.height = view.height;
  img.rgb.assign(static_cast<std::size_t>(view.width) * view.height * 3, 0.0f);
  detail::blend_tiles(projected, view, 0, view.grid_y, offsets, entries, options, img.rgb.data());
  st.blend += detail::now() - t2;
  return img;
}

Image render_brute_force(const SplatFrame& splats, const Camera& camera,
                         const RenderOptions& options) {
  const detail::View view(camera);
  const detail::ThreadScope threads(1);
  std::vector<Projected> projected;
  detail::preprocess(splats, view, projected);
  std::sort(projected.begin(), projected.end(),
            [](const Projected& a, const Projected& b) { return detail::before(a, b); });
  Image img;
  img.width = view.width;
  img.height = view.height;
  img.rgb.assign(static_cast<std::size_t>(view.width) * view.height * 3, 0.0f);
  for (int py = 0; py < view.height; ++py)
    for (int px = 0; px < view.width; ++px) {
      const int tx = px / detail::kTile, ty = py / detail::kTile;
      // The splats whose rectangle covers this pixel's tile, in the global order.
      float T = 1.0f;
      float C[3] = {0, 0, 0};
      for (const Projected& g : projected)
        if (tx >= g.x0 && tx < g.x1 && ty >= g.y0 && ty < g.y1 &&
            !detail::blend_step(g, detail::power_cut(g.opacity), static_cast<float>(px),
                                static_cast<float>(py), T, C))
          break;
      float* out = &img.rgb[(static_cast<std::size_t>(py) * view.width + px) * 3];
      for (int ch = 0; ch < 3; ++ch) out[ch] = C[ch] + T * options.background[ch];
    }
  return img;
}

void write_image_png(const std::string& path, const Image& image) {
  if (image.width < 1 || image.height < 1 ||
      image.rgb.size() != static_cast<std::size_t>(image.width) * image.height * 3)
    throw std::logic_error("write_image_png: the image is empty or its size does not match");
  std::vector<std::uint8_t> bytes(image.rgb.size());
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    const float v = image.rgb[i];
    const float c = v > 0.0f ? (v < 1.0f ? v : 1.0f) : 0.0f;  // NaN -> 0
    bytes[i] = static_cast<std::uint8_t>(std::lround(c * 255.0f));
  }
  io::write_png_rgb(path, image.width, image.height, bytes);
}

double psnr(const Image& a, const Image& b) {
  if (a.width != b.width || a.height != b.height || a.rgb.size() != b.rgb.size() || a.rgb.empty())
    throw std::invalid_argument("psnr: the images differ in size or are empty");
  double se = 0;
  for (std::size_t i = 0; i < a.rgb.size(); ++i) {
    const double d = static_cast<double>(a.rgb[i]) - b.rgb[i];
    se += d * d;
  }
  const double mse = se / static_cast<double>(a.rgb.size());
  return mse == 0 ? INFINITY : 10.0 * std::log10(1.0 / mse);
}

}  // namespace gen4d::gaussians

namespace gen4d::gaussians {

std::array<std::array<double, 3>, 2> central_box(const SplatFrame& splats) {
  const std::size_t n = splats.size();
  if (n == 0) throw InputError("framing camera: there are no splats to frame");
  std::array<std::array<double, 3>, 2> box;
  std::vector<float> axis(n);
  for (int a = 0; a < 3; ++a) {
    for (std::size_t i = 0; i < n; ++i) axis[i] = splats.position[3 * i + a];
    const std::size_t i_lo = (n - 1) * 2 / 100, i_hi = (n - 1) * 98 / 100;
    std::nth_element(axis.begin(), axis.begin() + static_cast<long>(i_lo), axis.end());
    box[0][a] = axis[i_lo];
    std::nth_element(axis.begin(), axis.begin() + static_cast<long>(i_hi), axis.end());
    box[1][a] = axis[i_hi];
  }
  return box;
}

OrbitCamera framing_orbit(const std::array<double, 3>& lo, const std::array<double, 3>& hi,
                          int width, int height, double fov_y_degrees,
                          const std::array<double, 3>& up) {
  OrbitCamera orbit;
  orbit.up = up;
  orbit.width = width;
  orbit.height = height;
  orbit.fov_y_degrees = fov_y_degrees;
  orbit.azimuth = 45;
  orbit.elevation = 20;
  double r2 = 0;
  for (int a = 0; a < 3; ++a) {
    orbit.center[a] = 0.5 * (lo[a] + hi[a]);
    r2 += 0.25 * (hi[a] - lo[a]) * (hi[a] - lo[a]);
  }
  const double half_fov_y = fov_y_degrees * 3.14159265358979323846 / 360.0;
  const double half_fov_x = std::atan(std::tan(half_fov_y) * width / height);
  const double sphere = std::max(std::sqrt(r2), 1e-6);
  orbit.radius = 1.05 * sphere / std::sin(std::min(half_fov_x, half_fov_y));
  return orbit;
}

OrbitCamera framing_orbit(const SplatFrame& splats, int width, int height, double fov_y_degrees,
                          const std::array<double, 3>& up) {
  const auto box = central_box(splats);
  return framing_orbit(box[0], box[1], width, height, fov_y_degrees, up);
}

}  // namespace gen4d::gaussians
