//! Internals shared by the serial, distributed and GPU renderers (not part of the public API):
//! the per-splat projection and the per-pixel compositing step as GEN4D_HD functions, so the
//! host loops and the CUDA kernels run the same source.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <vector>

#include "gaussians/Camera.hpp"
#include "gaussians/Render.hpp"
#include "gaussians/SphericalHarmonics.hpp"
#include "gaussians/Splats.hpp"
#include "materials/Hd.hpp"

namespace gen4d::gaussians::detail {

inline constexpr int kTile = 16;

//! A visible splat after preprocessing: screen position, conic, opacity, colour, view depth,
//! and the tile rectangle [x0, x1) x [y0, y1) it is drawn in. Trivially copyable (sent as bytes).
struct Projected {
  //! Uninitialised: buffers of them are sized without being zeroed.
  GEN4D_HD Projected() {}
  float x, y;
  float conic[3];
  float opacity;
  float rgb[3];
  float depth;
  float radius;
  std::uint16_t x0, y0, x1, y1;
};

//! Per-render camera quantities in single precision, as the rasterizer holds them.
struct View {
  int width = 0, height = 0, grid_x = 0, grid_y = 0;
  float view[9];   //!< world -> camera rotation, row-major (R^T)
  float trans[3];  //!< world -> camera translation (-R^T position)
  float campos[3];
  float fx, fy, tan_fovx, tan_fovy, cx, cy;
  explicit View(const Camera& camera);
};

//! A SplatFrame's arrays as a kernel captures them (sh_rotation null when absent).
struct SplatPointers {
  const float* position = nullptr;
  const float* covariance = nullptr;
  const float* opacity = nullptr;
  const float* sh = nullptr;
  const float* sh_rotation = nullptr;
  int sh_degree = 0;
};

//! std::min / std::max with their argument order and NaN behaviour, on host and device.
GEN4D_HD inline float hd_min(float a, float b) {
  return b < a ? b : a;
}
GEN4D_HD inline float hd_max(float a, float b) {
  return a < b ? b : a;
}

GEN4D_HD inline std::uint32_t float_bits(float f) {
#if defined(__CUDA_ARCH__)
  return __float_as_uint(f);
#else
  std::uint32_t u;
  std::memcpy(&u, &f, sizeof u);
  return u;
#endif
}

//! forward.cu's getRect for one coordinate: min(grid, max(0, (int)v)) without overflow.
GEN4D_HD inline std::uint16_t tile_bound(float v, int grid) {
  if (!(v > 0.0f)) return 0;
  if (v >= static_cast<float>(grid)) return static_cast<std::uint16_t>(grid);
  return static_cast<std::uint16_t>(static_cast<int>(v));
}

//! preprocessCUDA for splat i (computeCov2D, computeColorFromSH): false when it is culled
//! (view depth <= 0.2, a singular screen covariance, or a rectangle of no tile), else `g`.
GEN4D_HD inline bool project(const SplatPointers& s, const View& v, long i, Projected& g) {
  const float* W = v.view;
  const float* p = s.position + 3 * i;
  // Near culling (in_frustum): view depth must exceed 0.2.
  const float tx = W[0] * p[0] + W[1] * p[1] + W[2] * p[2] + v.trans[0];
  const float ty = W[3] * p[0] + W[4] * p[1] + W[5] * p[2] + v.trans[1];
  const float tz = W[6] * p[0] + W[7] * p[1] + W[8] * p[2] + v.trans[2];
  if (!(tz > 0.2f)) return false;
  // computeCov2D: EWA projection with the Jacobian at a clamped mean.
  const float limx = 1.3f * v.tan_fovx, limy = 1.3f * v.tan_fovy;
  const float cxz = hd_min(limx, hd_max(-limx, tx / tz)) * tz;
  const float cyz = hd_min(limy, hd_max(-limy, ty / tz)) * tz;
  const float j00 = v.fx / tz, j02 = -(v.fx * cxz) / (tz * tz);
  const float j11 = v.fy / tz, j12 = -(v.fy * cyz) / (tz * tz);
  // M = J W (2 x 3)
  float M[2][3];
  for (int k = 0; k < 3; ++k) {
    M[0][k] = j00 * W[k] + j02 * W[6 + k];
    M[1][k] = j11 * W[3 + k] + j12 * W[6 + k];
  }
  const float* c = s.covariance + 6 * i;
  const float S[3][3] = {{c[0], c[1], c[2]}, {c[1], c[3], c[4]}, {c[2], c[4], c[5]}};
  float MS[2][3];
  for (int r = 0; r < 2; ++r)
    for (int k = 0; k < 3; ++k)
      MS[r][k] = M[r][0] * S[0][k] + M[r][1] * S[1][k] + M[r][2] * S[2][k];
  float a = MS[0][0] * M[0][0] + MS[0][1] * M[0][1] + MS[0][2] * M[0][2];
  const float b = MS[0][0] * M[1][0] + MS[0][1] * M[1][1] + MS[0][2] * M[1][2];
  float d = MS[1][0] * M[1][0] + MS[1][1] * M[1][1] + MS[1][2] * M[1][2];
  a += 0.3f;  // low-pass filter: at least about a pixel wide
  d += 0.3f;
  const float det = a * d - b * b;
  if (det == 0.0f) return false;
  const float det_inv = 1.f / det;
  const float mid = 0.5f * (a + d);
  const float l1 = mid + sqrtf(hd_max(0.1f, mid * mid - det));
  const float l2 = mid - sqrtf(hd_max(0.1f, mid * mid - det));
  const float radius = ceilf(3.f * sqrtf(hd_max(l1, l2)));
  g.x = v.fx * (tx / tz) + v.cx;
  g.y = v.fy * (ty / tz) + v.cy;
  g.x0 = tile_bound((g.x - radius) / kTile, v.grid_x);
  g.y0 = tile_bound((g.y - radius) / kTile, v.grid_y);
  g.x1 = tile_bound((g.x + radius + kTile - 1) / kTile, v.grid_x);
  g.y1 = tile_bound((g.y + radius + kTile - 1) / kTile, v.grid_y);
  if (g.x1 <= g.x0 || g.y1 <= g.y0) return false;
  g.conic[0] = d * det_inv;
  g.conic[1] = -b * det_inv;
  g.conic[2] = a * det_inv;
  g.opacity = s.opacity[i];
  g.depth = tz;
  g.radius = radius;
  // computeColorFromSH: direction from the camera centre to the mean.
  float dir[3] = {p[0] - v.campos[0], p[1] - v.campos[1], p[2] - v.campos[2]};
  const float len = sqrtf(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
  for (float& x : dir) x = x / len;
  if (s.sh_rotation) {  // harmonics rotated with the material: evaluate at R^T d
    const float* R = s.sh_rotation + 9 * i;
    const float r0 = R[0] * dir[0] + R[3] * dir[1] + R[6] * dir[2];
    const float r1 = R[1] * dir[0] + R[4] * dir[1] + R[7] * dir[2];
    const float r2 = R[2] * dir[0] + R[5] * dir[1] + R[8] * dir[2];
    dir[0] = r0;
    dir[1] = r1;
    dir[2] = r2;
  }
  const long k = (s.sh_degree + 1) * (s.sh_degree + 1);
  sh_color(s.sh_degree, s.sh + 3 * k * i, dir[0], dir[1], dir[2], g.rgb);
  return true;
}

//! The canonical front-to-back order: view depth, then the projected data bitwise.
GEN4D_HD inline bool before(const Projected& a, const Projected& b) {
  if (a.depth != b.depth) return a.depth < b.depth;
  const float fa[] = {a.x,       a.y,      a.conic[0], a.conic[1], a.conic[2],
                      a.opacity, a.rgb[0], a.rgb[1],   a.rgb[2],   a.radius};
  const float fb[] = {b.x,       b.y,      b.conic[0], b.conic[1], b.conic[2],
                      b.opacity, b.rgb[0], b.rgb[1],   b.rgb[2],   b.radius};
  for (int k = 0; k < 10; ++k)
    if (float_bits(fa[k]) != float_bits(fb[k])) return float_bits(fa[k]) < float_bits(fb[k]);
  return false;  // identical data: interchangeable, the image does not depend on their order
}

//! Below this power a splat of opacity <= 1 cannot pass the alpha test: exp(-5.6) = 0.0037 <
//! 1/255, so skipping it there is exact (and saves the exp).
GEN4D_HD inline float power_cut(float opacity) {
  return opacity <= 1.0f ? -5.6f : -std::numeric_limits<float>::infinity();
}

//! The tightest such cut for this opacity: o exp(power) < 1/255 below log(1 / (255 o)); 1e-3
//! lower, so that the float rounding of the cut, the exp and the product (about 1e-7) cannot
//! let a skipped power pass the alpha test. Exact as a skip, never below power_cut.
inline float alpha_cut(float opacity) {
  if (!(opacity <= 1.0f)) return power_cut(opacity);
  if (opacity <= 0.0f) return std::numeric_limits<float>::infinity();  // alpha <= 0
  return std::log(1.0f / (255.0f * opacity)) - 1e-3f;
}

//! The Gaussian's exponent at pixel centre (px, py), in renderCUDA's order of operations.
GEN4D_HD inline float splat_power(const Projected& g, float px, float py) {
  const float dx = g.x - px, dy = g.y - py;
  return -0.5f * (g.conic[0] * dx * dx + g.conic[2] * dy * dy) - g.conic[1] * dx * dy;
}

//! renderCUDA's compositing of splat `g` with exponent `power` (in [cut, 0]) onto the colour C
//! and the transmittance T: alpha = min(0.99, o exp(power)), skipped below 1/255. Returns false,
//! C and T untouched, when the splat would take T below 1e-4 (the pixel is finished).
GEN4D_HD inline bool blend_power(const Projected& g, float power, float& T, float* C) {
  const float alpha = hd_min(0.99f, g.opacity * expf(power));
  if (alpha < 1.0f / 255.0f) return true;
  const float test_T = T * (1 - alpha);
  if (test_T < 0.0001f) return false;
  C[0] += g.rgb[0] * alpha * T;
  C[1] += g.rgb[1] * alpha * T;
  C[2] += g.rgb[2] * alpha * T;
  T = test_T;
  return true;
}

//! One splat at one pixel centre (px, py): skipped where the power is above 0 or below `cut`
//! (an exact shortcut of the alpha test), else blend_power.
GEN4D_HD inline bool blend_step(const Projected& g, float cut, float px, float py, float& T,
                                float* C) {
  const float power = splat_power(g, px, py);
  if (power > 0.0f) return true;
  if (power < cut) return true;
  return blend_power(g, power, T, C);
}

//! The projection kernel: splat i's Projected into out[i] and the number of tiles it is drawn
//! in into touched[i] (0 when culled).
struct ProjectKernel {
  SplatPointers splats;
  View view;
  Projected* out;
  unsigned long long* touched;
  GEN4D_HD void operator()(long i) const {
    Projected g;
    if (project(splats, view, i, g)) {
      out[i] = g;
      touched[i] = static_cast<unsigned long long>(g.x1 - g.x0) * (g.y1 - g.y0);
    } else {
      touched[i] = 0;
    }
  }
};

//! The per-pixel blend kernel (renderCUDA): index i is pixel i % 256 of tile i / 256 of tile
//! rows [row0, ...), tiles row-major, the 16x16 pixels row-major, so a thread block walks one
//! tile's list together. Tile t's splats are splats[entries[offsets[t] .. offsets[t + 1])],
//! front to back; rgb holds the image rows from row0 * 16 on.
struct BlendPixelKernel {
  const Projected* splats;
  const std::uint32_t* offsets;
  const std::uint32_t* entries;
  float* rgb;
  int width, height, grid_x, row0;
  float bg[3];
  GEN4D_HD void operator()(long i) const {
    const long tile = i / (kTile * kTile);
    const int lx = static_cast<int>(i % kTile), ly = static_cast<int>((i / kTile) % kTile);
    const int px = static_cast<int>(tile % grid_x) * kTile + lx;
    const int py = (row0 + static_cast<int>(tile / grid_x)) * kTile + ly;
    if (px >= width || py >= height) return;
    float T = 1.0f;
    float C[3] = {0, 0, 0};
    const float fx = static_cast<float>(px), fy = static_cast<float>(py);
    for (std::uint32_t j = offsets[tile], end = offsets[tile + 1]; j < end; ++j) {
      const Projected& g = splats[entries[j]];
      if (!blend_step(g, power_cut(g.opacity), fx, fy, T, C)) break;
    }
    float* out = rgb + (static_cast<long>(py - row0 * kTile) * width + px) * 3;
    for (int ch = 0; ch < 3; ++ch) out[ch] = C[ch] + T * bg[ch];
  }
};

//! The frame's arrays as pointers; std::logic_error when their sizes do not match.
SplatPointers pointers(const SplatFrame& splats);

//! Appends the visible splats of `splats` (culling as forward.cu's preprocessCUDA) to `out`.
void preprocess(const SplatFrame& splats, const View& view, std::vector<Projected>& out);

//! Bins `splats` into tile rows [row0, row1): `offsets` (one per tile of those rows, plus one)
//! index `entries`, which lists each tile's splats (indices into `splats`) front to back in the
//! canonical order. A radix sort of the depths; `legacy`: the comparison sort it replaced, which
//! also permutes `splats` into that order (the same lists of splats).
void bin_tiles(std::vector<Projected>& splats, const View& view, int row0, int row1,
               std::vector<std::uint32_t>& offsets, std::vector<std::uint32_t>& entries,
               bool legacy = false);

//! Blends the tiles of rows [row0, row1) into `rgb` (rows row0 * 16 .. of the image, 3 floats
//! per pixel) on the host threads: each tile's pixels take its splats in order, each splat
//! only where it can pass the alpha test, until every pixel is finished. `legacy`: each pixel
//! walks the whole list on its own, as before (the same image bit for bit).
void blend_tiles(const std::vector<Projected>& splats, const View& view, int row0, int row1,
                 const std::vector<std::uint32_t>& offsets,
                 const std::vector<std::uint32_t>& entries, const RenderOptions& options,
                 float* rgb);

//! Sets the host threads to options.threads (when > 0) for its lifetime.
class ThreadScope {
 public:
  explicit ThreadScope(int threads);
  ~ThreadScope();
  ThreadScope(const ThreadScope&) = delete;
  ThreadScope& operator=(const ThreadScope&) = delete;

 private:
  int saved_ = 0;
};

//! Whether `options` send this render to the GPU (a CUDA build, a device, options.device and
//! not options.legacy).
bool on_device(const RenderOptions& options);

#if defined(GEN4D_CUDA)
//! The renderer's GPU buffers (Render.cu): the last uploaded frame stays on the device.
class DeviceRenderer {
 public:
  DeviceRenderer();
  ~DeviceRenderer();
  DeviceRenderer(const DeviceRenderer&) = delete;
  DeviceRenderer& operator=(const DeviceRenderer&) = delete;
  //! Copies the frame's arrays to the device.
  void upload(const SplatFrame& splats);
  //! The uploaded frame: projected (ProjectKernel), binned (radix sort of (tile, depth) keys,
  //! equal keys put in the canonical order) and blended (BlendPixelKernel) on the device.
  Image render(const View& view, const RenderOptions& options);
  //! The uploaded frame's visible splats, projected on the device, appended to `out`.
  void preprocess(const View& view, std::vector<Projected>& out);
  //! blend_tiles on the device (tile lists built on the host).
  void blend(const std::vector<Projected>& splats, const View& view, int row0, int row1,
             const std::vector<std::uint32_t>& offsets, const std::vector<std::uint32_t>& entries,
             const RenderOptions& options, float* rgb);

 private:
  struct Buffers;
  std::unique_ptr<Buffers> b_;
};

//! This process's renderer on its GPU.
DeviceRenderer& device_renderer();
#endif

}  // namespace gen4d::gaussians::detail
