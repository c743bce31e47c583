// CPU port of the forward pass of the 3DGS rasterizer (graphdeco-inria diff-gaussian-
// rasterization: preprocessCUDA, computeCov2D, computeColorFromSH, renderCUDA), single
// precision throughout as there.
#include "gaussians/Render.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>
#include <thread>

#include "core/Error.hpp"
#include "gaussians/RenderDetail.hpp"
#include "gaussians/SphericalHarmonics.hpp"
#include "io/PngPreview.hpp"

namespace gen4d::gaussians {
namespace detail {

namespace {

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

//! Runs body(i) for i in [0, n) on `threads` threads, items handed out one at a time.
template <class F>
void parallel_for(int n, int threads, F&& body) {
  threads = std::max(1, std::min(threads, n));
  if (threads == 1) {
    for (int i = 0; i < n; ++i) body(i);
    return;
  }
  std::atomic<int> next{0};
  auto work = [&] {
    for (int i = next++; i < n; i = next++) body(i);
  };
  std::vector<std::thread> pool;
  pool.reserve(static_cast<std::size_t>(threads - 1));
  for (int t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
}

std::uint32_t bits(float f) {
  std::uint32_t u;
  std::memcpy(&u, &f, sizeof u);
  return u;
}

//! forward.cu's getRect for one coordinate: min(grid, max(0, (int)v)) without overflow.
std::uint16_t tile_bound(float v, int grid) {
  if (!(v > 0.0f)) return 0;
  if (v >= static_cast<float>(grid)) return static_cast<std::uint16_t>(grid);
  return static_cast<std::uint16_t>(static_cast<int>(v));
}

void check_frame(const SplatFrame& s) {
  const std::size_t n = s.size();
  const std::size_t k = static_cast<std::size_t>(sh_coefficients(s.sh_degree));
  if (s.sh_degree < 0 || s.sh_degree > kMaxShDegree || s.position.size() != 3 * n ||
      s.covariance.size() != 6 * n || s.sh.size() != 3 * k * n ||
      !(s.sh_rotation.empty() || s.sh_rotation.size() == 9 * n))
    throw std::logic_error("render: SplatFrame arrays do not match its size and SH degree");
}

}  // namespace

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

void preprocess(const SplatFrame& s, const View& v, std::vector<Projected>& out, int threads) {
  check_frame(s);
  const std::size_t n = s.size();
  const int K = sh_coefficients(s.sh_degree);
  const bool rotate = !s.sh_rotation.empty();
  const int chunks = static_cast<int>(std::min<std::size_t>(
      static_cast<std::size_t>(std::max(1, threads)) * 4, std::max<std::size_t>(1, n / 4096)));
  std::vector<std::vector<Projected>> parts(static_cast<std::size_t>(chunks));
  parallel_for(chunks, threads, [&](int ci) {
    const std::size_t lo = n * static_cast<std::size_t>(ci) / static_cast<std::size_t>(chunks);
    const std::size_t hi = n * static_cast<std::size_t>(ci + 1) / static_cast<std::size_t>(chunks);
    auto& part = parts[static_cast<std::size_t>(ci)];
    part.reserve(hi - lo);
    const float* W = v.view;
    for (std::size_t i = lo; i < hi; ++i) {
      const float* p = &s.position[3 * i];
      // Near culling (in_frustum): view depth must exceed 0.2.
      const float tx = W[0] * p[0] + W[1] * p[1] + W[2] * p[2] + v.trans[0];
      const float ty = W[3] * p[0] + W[4] * p[1] + W[5] * p[2] + v.trans[1];
      const float tz = W[6] * p[0] + W[7] * p[1] + W[8] * p[2] + v.trans[2];
      if (!(tz > 0.2f)) continue;
      // computeCov2D: EWA projection with the Jacobian at a clamped mean.
      const float limx = 1.3f * v.tan_fovx, limy = 1.3f * v.tan_fovy;
      const float cxz = std::min(limx, std::max(-limx, tx / tz)) * tz;
      const float cyz = std::min(limy, std::max(-limy, ty / tz)) * tz;
      const float j00 = v.fx / tz, j02 = -(v.fx * cxz) / (tz * tz);
      const float j11 = v.fy / tz, j12 = -(v.fy * cyz) / (tz * tz);
      // M = J W (2 x 3)
      float M[2][3];
      for (int k = 0; k < 3; ++k) {
        M[0][k] = j00 * W[k] + j02 * W[6 + k];
        M[1][k] = j11 * W[3 + k] + j12 * W[6 + k];
      }
      const float* c = &s.covariance[6 * i];
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
      if (det == 0.0f) continue;
      const float det_inv = 1.f / det;
      const float mid = 0.5f * (a + d);
      const float l1 = mid + std::sqrt(std::max(0.1f, mid * mid - det));
      const float l2 = mid - std::sqrt(std::max(0.1f, mid * mid - det));
      const float radius = std::ceil(3.f * std::sqrt(std::max(l1, l2)));
      Projected g;
      g.x = v.fx * (tx / tz) + v.cx;
      g.y = v.fy * (ty / tz) + v.cy;
      g.x0 = tile_bound((g.x - radius) / kTile, v.grid_x);
      g.y0 = tile_bound((g.y - radius) / kTile, v.grid_y);
      g.x1 = tile_bound((g.x + radius + kTile - 1) / kTile, v.grid_x);
      g.y1 = tile_bound((g.y + radius + kTile - 1) / kTile, v.grid_y);
      if (g.x1 <= g.x0 || g.y1 <= g.y0) continue;
      g.conic[0] = d * det_inv;
      g.conic[1] = -b * det_inv;
      g.conic[2] = a * det_inv;
      g.opacity = s.opacity[i];
      g.depth = tz;
      g.radius = radius;
      // computeColorFromSH: direction from the camera centre to the mean.
      float dir[3] = {p[0] - v.campos[0], p[1] - v.campos[1], p[2] - v.campos[2]};
      const float len = std::sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
      for (float& x : dir) x = x / len;
      if (rotate) {  // harmonics rotated with the material: evaluate at R^T d
        const float* R = &s.sh_rotation[9 * i];
        const float r0 = R[0] * dir[0] + R[3] * dir[1] + R[6] * dir[2];
        const float r1 = R[1] * dir[0] + R[4] * dir[1] + R[7] * dir[2];
        const float r2 = R[2] * dir[0] + R[5] * dir[1] + R[8] * dir[2];
        dir[0] = r0;
        dir[1] = r1;
        dir[2] = r2;
      }
      sh_color(s.sh_degree, &s.sh[3 * static_cast<std::size_t>(K) * i], dir[0], dir[1], dir[2],
               g.rgb);
      part.push_back(g);
    }
  });
  std::size_t total = out.size();
  for (const auto& part : parts) total += part.size();
  out.reserve(total);
  for (const auto& part : parts) out.insert(out.end(), part.begin(), part.end());
}

bool before(const Projected& a, const Projected& b) {
  if (a.depth != b.depth) return a.depth < b.depth;
  const float fa[] = {a.x,       a.y,      a.conic[0], a.conic[1], a.conic[2],
                      a.opacity, a.rgb[0], a.rgb[1],   a.rgb[2],   a.radius};
  const float fb[] = {b.x,       b.y,      b.conic[0], b.conic[1], b.conic[2],
                      b.opacity, b.rgb[0], b.rgb[1],   b.rgb[2],   b.radius};
  for (int k = 0; k < 10; ++k)
    if (bits(fa[k]) != bits(fb[k])) return bits(fa[k]) < bits(fb[k]);
  return false;  // identical data: interchangeable, the image does not depend on their order
}

void bin_tiles(std::vector<Projected>& splats, const View& v, int row0, int row1,
               std::vector<std::uint32_t>& offsets, std::vector<std::uint32_t>& entries) {
  // Sort (depth bits, index) pairs (depths are positive: their bits order like the values),
  // breaking ties with the full canonical comparison, then permute once.
  const std::size_t n = splats.size();
  if (n > 0xffffffffu) throw RuntimeError("render: more than 2^32 visible splats");
  std::vector<std::uint64_t> keys(n);
  for (std::size_t i = 0; i < n; ++i)
    keys[i] = (static_cast<std::uint64_t>(bits(splats[i].depth)) << 32) | i;
  std::sort(keys.begin(), keys.end(), [&](std::uint64_t a, std::uint64_t b) {
    if ((a >> 32) != (b >> 32)) return a < b;
    return before(splats[a & 0xffffffffu], splats[b & 0xffffffffu]);
  });
  std::vector<Projected> sorted(n);
  for (std::size_t i = 0; i < n; ++i) sorted[i] = splats[keys[i] & 0xffffffffu];
  splats.swap(sorted);

  const int gx = v.grid_x;
  const std::size_t tiles = static_cast<std::size_t>(row1 - row0) * static_cast<std::size_t>(gx);
  offsets.assign(tiles + 1, 0);
  for (const Projected& g : splats) {
    const int y0 = std::max<int>(g.y0, row0), y1 = std::min<int>(g.y1, row1);
    for (int ty = y0; ty < y1; ++ty)
      for (int tx = g.x0; tx < g.x1; ++tx)
        ++offsets[static_cast<std::size_t>(ty - row0) * gx + tx + 1];
  }
  for (std::size_t t = 0; t < tiles; ++t) offsets[t + 1] += offsets[t];
  if (offsets[tiles] > 0xffffffffu) throw RuntimeError("render: too many tile entries");
  entries.resize(offsets[tiles]);
  std::vector<std::uint32_t> fill(offsets.begin(), offsets.end() - 1);
  for (std::size_t i = 0; i < n; ++i) {
    const Projected& g = splats[i];
    const int y0 = std::max<int>(g.y0, row0), y1 = std::min<int>(g.y1, row1);
    for (int ty = y0; ty < y1; ++ty)
      for (int tx = g.x0; tx < g.x1; ++tx)
        entries[fill[static_cast<std::size_t>(ty - row0) * gx + tx]++] =
            static_cast<std::uint32_t>(i);
  }
}

namespace {

//! One pixel of renderCUDA: front-to-back compositing of `count` splats given as structure
//! of arrays, returning C + T bg.
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
    // exp(power) < 1/255 there: the alpha test below would skip it (an exact shortcut).
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
  // For o <= 1, o exp(power) < 1/255 whenever power < -5.6 (exp(-5.6) = 0.0037 < 0.0039).
  t.cut[j] = g.opacity <= 1.0f ? -5.6f : -INFINITY;
}

}  // namespace

void blend_tiles(const std::vector<Projected>& splats, const View& v, int row0, int row1,
                 const std::vector<std::uint32_t>& offsets,
                 const std::vector<std::uint32_t>& entries, const RenderOptions& options,
                 float* rgb, int threads) {
  const int gx = v.grid_x;
  const int tiles = (row1 - row0) * gx;
  const float bg[3] = {options.background[0], options.background[1], options.background[2]};
  std::vector<TileData> scratch(static_cast<std::size_t>(std::max(1, threads)));
  std::atomic<int> slot{0};
  auto body = [&](int tile, TileData& t) {
    const int ty = row0 + tile / gx, tx = tile % gx;
    const std::size_t lo = offsets[static_cast<std::size_t>(tile)];
    const std::size_t hi = offsets[static_cast<std::size_t>(tile) + 1];
    const std::size_t count = hi - lo;
    if (t.x.size() < count) t.resize(count);
    for (std::size_t j = 0; j < count; ++j) load(t, j, splats[entries[lo + j]]);
    const int x_end = std::min((tx + 1) * kTile, v.width);
    const int y_end = std::min((ty + 1) * kTile, v.height);
    for (int py = ty * kTile; py < y_end; ++py)
      for (int px = tx * kTile; px < x_end; ++px) {
        float* out = rgb + (static_cast<std::size_t>(py - row0 * kTile) * v.width + px) * 3;
        blend_pixel(t, count, static_cast<float>(px), static_cast<float>(py), bg, out);
      }
  };
  threads = std::max(1, std::min(threads, tiles));
  if (threads == 1) {
    for (int i = 0; i < tiles; ++i) body(i, scratch[0]);
    return;
  }
  std::atomic<int> next{0};
  auto work = [&] {
    TileData& t = scratch[static_cast<std::size_t>(slot++)];
    for (int i = next++; i < tiles; i = next++) body(i, t);
  };
  std::vector<std::thread> pool;
  for (int k = 1; k < threads; ++k) pool.emplace_back(work);
  work();
  for (auto& th : pool) th.join();
}

int thread_count(const RenderOptions& options, int sharing) {
  if (options.threads > 0) return options.threads;
  const int hw = static_cast<int>(std::thread::hardware_concurrency());
  return std::max(1, (hw > 0 ? hw : 1) / std::max(1, sharing));
}

}  // namespace detail

using detail::Projected;

Image render(const SplatFrame& splats, const Camera& camera, const RenderOptions& options) {
  const detail::View view(camera);
  const int threads = detail::thread_count(options, 1);
  RenderStats local;
  RenderStats& st = options.stats ? *options.stats : local;
  double t0 = detail::now();
  std::vector<Projected> projected;
  detail::preprocess(splats, view, projected, threads);
  double t1 = detail::now();
  st.preprocess += t1 - t0;
  st.visible += projected.size();
  std::vector<std::uint32_t> offsets, entries;
  detail::bin_tiles(projected, view, 0, view.grid_y, offsets, entries);
  double t2 = detail::now();
  st.sort += t2 - t1;
  st.tile_entries += entries.size();
  Image img;
  img.width = view.width;
  img.height = view.height;
  img.rgb.assign(static_cast<std::size_t>(view.width) * view.height * 3, 0.0f);
  detail::blend_tiles(projected, view, 0, view.grid_y, offsets, entries, options, img.rgb.data(),
                      threads);
  st.blend += detail::now() - t2;
  return img;
}

Image render_brute_force(const SplatFrame& splats, const Camera& camera,
                         const RenderOptions& options) {
  const detail::View view(camera);
  std::vector<Projected> projected;
  detail::preprocess(splats, view, projected, 1);
  std::sort(projected.begin(), projected.end(), detail::before);
  Image img;
  img.width = view.width;
  img.height = view.height;
  img.rgb.assign(static_cast<std::size_t>(view.width) * view.height * 3, 0.0f);
  const float bg[3] = {options.background[0], options.background[1], options.background[2]};
  for (int py = 0; py < view.height; ++py)
    for (int px = 0; px < view.width; ++px) {
      const int tx = px / detail::kTile, ty = py / detail::kTile;
      // The splats whose rectangle covers this pixel's tile, in the global order.
      detail::TileData t;
      std::size_t count = 0;
      for (const Projected& g : projected)
        if (tx >= g.x0 && tx < g.x1 && ty >= g.y0 && ty < g.y1) ++count;
      t.resize(count);
      count = 0;
      for (const Projected& g : projected)
        if (tx >= g.x0 && tx < g.x1 && ty >= g.y0 && ty < g.y1) detail::load(t, count++, g);
      detail::blend_pixel(t, count, static_cast<float>(px), static_cast<float>(py), bg,
                          &img.rgb[(static_cast<std::size_t>(py) * view.width + px) * 3]);
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
