// The 3DGS renderer against analytic images and its own brute-force reference, the SH basis,
// the distributed render at 1, 2 and 4 ranks (bit for bit), cameras and cameras.json, JSON.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "core/Error.hpp"
#include "gaussians/Camera.hpp"
#include "gaussians/Json.hpp"
#include "gaussians/Render.hpp"
#include "gaussians/SphericalHarmonics.hpp"
#include "gaussians/Video.hpp"
#include "../drivers/SyntheticSplats.hpp"
#include "png_test_util.hpp"
#include "mpi_test_util.hpp"

namespace gen4d::gaussians {
namespace {

namespace fs = std::filesystem;
constexpr float kC0 = 0.28209479177387814f;

using test::rank_of;
using test::size_of;

//! A scratch directory per rank and test.
fs::path scratch(const std::string& name) {
  const fs::path d = fs::path(GEN4D_BINARY_DIR) / "tests" / "scratch" / "render" /
                     (name + "_r" + std::to_string(rank_of(MPI_COMM_WORLD)) + "_n" +
                      std::to_string(size_of(MPI_COMM_WORLD)));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

//! Camera at the origin looking along +z (x right, y down), focal f, square pixels.
Camera axis_camera(int w, int h, double f) {
  Camera c;
  c.width = w;
  c.height = h;
  c.fx = c.fy = f;
  return c;
}

//! Appends an SH-0 splat of colour `rgb` (the DC coefficient giving that colour).
void add_splat(SplatFrame& s, std::array<float, 3> p, std::array<float, 6> cov, float opacity,
               std::array<float, 3> rgb) {
  s.position.insert(s.position.end(), p.begin(), p.end());
  s.covariance.insert(s.covariance.end(), cov.begin(), cov.end());
  s.opacity.push_back(opacity);
  const int k = s.coefficients();
  // Exactly black where asked (the clamp at 0), else the DC coefficient giving that colour.
  for (int c = 0; c < 3; ++c) s.sh.push_back(rgb[c] == 0 ? -1.0f / kC0 : (rgb[c] - 0.5f) / kC0);
  for (int j = 1; j < k; ++j)
    for (int c = 0; c < 3; ++c) s.sh.push_back(0.0f);
}

std::array<float, 6> isotropic(float sigma) {
  const float v = sigma * sigma;
  return {v, 0, 0, v, 0, v};
}

//! A random SPD covariance R diag(s^2) R^T with scales in [lo, hi].
std::array<float, 6> random_cov(std::mt19937& rng, double lo, double hi) {
  const std::array<double, 6> c = synthetic::random_covariance(rng, lo, hi);
  return {float(c[0]), float(c[1]), float(c[2]), float(c[3]), float(c[4]), float(c[5])};
}

//! `n` random splats of SH degree `degree` in the box [-1,1]^2 x [zlo, zhi].
SplatFrame random_scene(int n, int degree, unsigned seed, float zlo = 2.0f, float zhi = 5.0f) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1), z(zlo, zhi), o(0.05f, 0.999f), c(-1.5f, 1.5f);
  SplatFrame s;
  s.sh_degree = degree;
  const int k = s.coefficients();
  for (int i = 0; i < n; ++i) {
    const std::array<float, 3> p{u(rng), u(rng), z(rng)};
    s.position.insert(s.position.end(), p.begin(), p.end());
    const auto cov = random_cov(rng, 0.01, 0.12);
    s.covariance.insert(s.covariance.end(), cov.begin(), cov.end());
    s.opacity.push_back(o(rng));
    for (int j = 0; j < 3 * k; ++j) s.sh.push_back(c(rng) * (j < 3 ? 1.0f : 0.4f));
  }
  return s;
}

//! Splat i of `s` appended to `out`.
void copy_splat(const SplatFrame& s, std::size_t i, SplatFrame& out) {
  out.sh_degree = s.sh_degree;
  const std::size_t k = static_cast<std::size_t>(s.coefficients());
  out.position.insert(out.position.end(), &s.position[3 * i], &s.position[3 * i] + 3);
  out.covariance.insert(out.covariance.end(), &s.covariance[6 * i], &s.covariance[6 * i] + 6);
  out.opacity.push_back(s.opacity[i]);
  out.sh.insert(out.sh.end(), &s.sh[3 * k * i], &s.sh[3 * k * i] + 3 * k);
  if (!s.sh_rotation.empty())
    out.sh_rotation.insert(out.sh_rotation.end(), &s.sh_rotation[9 * i], &s.sh_rotation[9 * i] + 9);
}

bool bitwise_equal(const Image& a, const Image& b) {
  return a.width == b.width && a.height == b.height && a.rgb.size() == b.rgb.size() &&
         std::memcmp(a.rgb.data(), b.rgb.data(), a.rgb.size() * sizeof(float)) == 0;
}

float max_diff(const Image& a, const Image& b) {
  float m = 0;
  for (std::size_t i = 0; i < a.rgb.size(); ++i) m = std::max(m, std::fabs(a.rgb[i] - b.rgb[i]));
  return m;
}

// --- spherical harmonics --------------------------------------------------------------------

// The 16 basis functions of sh_color are orthonormal on the sphere (Gauss-Legendre in cos theta
// times a uniform rule in phi integrates their degree <= 6 products exactly), which pins every
// constant and sign convention.
TEST(SphericalHarmonics, BasisIsOrthonormal) {
  const double gx[8] = {-0.9602898564975363, -0.7966664774136267, -0.5255324099163290,
                        -0.1834346424956498, 0.1834346424956498,  0.5255324099163290,
                        0.7966664774136267,  0.9602898564975363};
  const double gw[8] = {0.1012285362903763, 0.2223810344533745, 0.3137066458778873,
                        0.3626837833783620, 0.3626837833783620, 0.3137066458778873,
                        0.2223810344533745, 0.1012285362903763};
  const int nphi = 16;
  double gram[16][16] = {};
  for (int a = 0; a < 8; ++a)
    for (int b = 0; b < nphi; ++b) {
      const double ct = gx[a], st = std::sqrt(1 - ct * ct), phi = 2 * M_PI * (b + 0.5) / nphi;
      const float d[3] = {float(st * std::cos(phi)), float(st * std::sin(phi)), float(ct)};
      double Y[16];
      for (int k = 0; k < 16; ++k) {
        // Coefficient k = 1 on channel 0 and a DC offset keeping the colour positive.
        float sh[48] = {};
        sh[0] = 10.0f / kC0;
        sh[3 * k] += 1.0f;
        float rgb[3];
        sh_color(3, sh, d[0], d[1], d[2], rgb);
        Y[k] = double(rgb[0]) - 10.5;
      }
      const double w = gw[a] * 2 * M_PI / nphi;
      for (int k = 0; k < 16; ++k)
        for (int l = 0; l < 16; ++l) gram[k][l] += w * Y[k] * Y[l];
    }
  for (int k = 0; k < 16; ++k)
    for (int l = 0; l < 16; ++l)
      EXPECT_NEAR(gram[k][l], k == l ? 1.0 : 0.0, 2e-5) << "k=" << k << " l=" << l;
}

TEST(SphericalHarmonics, ClampsAndLowerDegreesIgnoreHigherCoefficients) {
  float sh[48];
  for (int i = 0; i < 48; ++i) sh[i] = 0.1f * float(i % 7) - 0.3f;
  sh[1] = -5.0f;  // green far negative: clamped to 0
  float a[3], b[3];
  sh_color(0, sh, 0.6f, 0.0f, 0.8f, a);
  EXPECT_FLOAT_EQ(a[0], kC0 * sh[0] + 0.5f);
  EXPECT_EQ(a[1], 0.0f);
  // Degree 1 by hand (x, y, z) = (0.6, 0, 0.8): - C1 y s1 + C1 z s2 - C1 x s3.
  const float c1 = 0.4886025119029199f;
  sh_color(1, sh, 0.6f, 0.0f, 0.8f, b);
  EXPECT_NEAR(b[2], kC0 * sh[2] + c1 * 0.8f * sh[8] - c1 * 0.6f * sh[11] + 0.5f, 1e-6);
}

// --- the rasterizer -------------------------------------------------------------------------

// An isotropic Gaussian of std sigma on the optical axis at depth z draws a screen Gaussian of
// variance (f sigma / z)^2 + 0.3 (the low-pass filter): fitted from the image's log profile, and
// every pixel equal to alpha = min(0.99, o exp(-r^2 / 2 s^2)) (white splat, black background).
TEST(Render, SingleGaussianProfile) {
  const float sigma = 0.05f, z = 2.0f, o = 0.8f;
  const double f = 100;
  const int w = 65, h = 65;  // principal point at pixel (32, 32)
  SplatFrame s;
  add_splat(s, {0, 0, z}, isotropic(sigma), o, {1, 1, 1});
  const Image img = render(s, axis_camera(w, h, f));
  const double s2 = std::pow(f * sigma / z, 2) + 0.3;
  // Least-squares fit of log(alpha) = log(o) - r^2 / (2 s^2) over the unclamped pixels.
  double sx = 0, sy = 0, sxx = 0, sxy = 0, n = 0, worst = 0;
  int lit = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float v = img.rgb[3 * (y * w + x)];
      EXPECT_EQ(v, img.rgb[3 * (y * w + x) + 2]);
      const double r2 = (x - 32.0) * (x - 32.0) + (y - 32.0) * (y - 32.0);
      const double exact = std::min(0.99, o * std::exp(-0.5 * r2 / s2));
      if (v > 0) {
        ++lit;
        worst = std::max(worst, std::fabs(v - exact));
        if (v < 0.98f && v > 0.01f) {
          const double ly = std::log(double(v));
          sx += r2, sy += ly, sxx += r2 * r2, sxy += r2 * ly, n += 1;
        }
      } else {
        EXPECT_LT(exact, 1.0 / 255 + 1e-6) << x << "," << y;  // only the alpha cut is black
      }
    }
  EXPECT_LT(worst, 2e-6);
  EXPECT_GT(lit, 100);
  const double slope = (n * sxy - sx * sy) / (n * sxx - sx * sx);
  const double fitted = -0.5 / slope;
  EXPECT_NEAR(fitted, s2, 1e-4 * s2) << "without the +0.3 it would be " << s2 - 0.3;
  // Moving it off-axis by one pixel's worth moves the image by one pixel.
  SplatFrame s2f;
  add_splat(s2f, {float(z / f), 0, z}, isotropic(sigma), o, {1, 1, 1});
  const Image moved = render(s2f, axis_camera(w, h, f));
  EXPECT_NEAR(moved.rgb[3 * (32 * w + 33)], img.rgb[3 * (32 * w + 32)], 1e-6);
}

// Front colour dominates whichever order the splats are listed in; exact values.
TEST(Render, OcclusionOrder) {
  SplatFrame a, b;
  a.sh_degree = b.sh_degree = 0;
  add_splat(a, {0, 0, 2}, isotropic(0.05f), 0.9f, {1, 0, 0});
  add_splat(a, {0, 0, 3}, isotropic(0.05f), 0.9f, {0, 1, 0});
  add_splat(b, {0, 0, 3}, isotropic(0.05f), 0.9f, {0, 1, 0});
  add_splat(b, {0, 0, 2}, isotropic(0.05f), 0.9f, {1, 0, 0});
  const Camera cam = axis_camera(33, 33, 100);
  const Image ia = render(a, cam), ib = render(b, cam);
  EXPECT_TRUE(bitwise_equal(ia, ib));
  const float* c = &ia.rgb[3 * (16 * 33 + 16)];
  // C = 0.9 red + (1 - 0.9) 0.9 green (the exact float arithmetic of the blend).
  const float r = 1.0f * 0.9f * 1.0f, g = 1.0f * 0.9f * (1.0f * (1 - 0.9f));
  EXPECT_NEAR(c[0], r, 1e-6);
  EXPECT_NEAR(c[1], g, 1e-6);
  EXPECT_GT(c[0], 5 * c[1]);
  // Behind the camera's near plane (depth 0.2) a splat is culled.
  SplatFrame near;
  add_splat(near, {0, 0, 0.19f}, isotropic(0.01f), 0.9f, {1, 1, 1});
  const Image in = render(near, cam);
  EXPECT_EQ(*std::max_element(in.rgb.begin(), in.rgb.end()), 0.0f);
}

// alpha is clamped at 0.99: one opaque black splat on white leaves 1 - 0.99 of the background.
TEST(Render, AlphaClamp) {
  SplatFrame s;
  add_splat(s, {0, 0, 2}, isotropic(0.05f), 1.0f, {0, 0, 0});
  RenderOptions opt;
  opt.background = {1, 1, 1};
  const Image img = render(s, axis_camera(33, 33, 100), opt);
  const float* c = &img.rgb[3 * (16 * 33 + 16)];
  for (int ch = 0; ch < 3; ++ch) EXPECT_EQ(c[ch], 1.0f - 0.99f);
  EXPECT_GE(c[0], 0.0099f);
}

// Compositing stops before the splat that would take transmittance below 1e-4: a stack of
// o = 0.9 splats lets exactly four contribute (in float 1 - 0.9f = 0.100000024, so T after
// four is 1.0000008e-4, and a fifth would give 1e-5), so the blue splats behind them add
// nothing, and the background gets the transmittance after four.
TEST(Render, TransmittanceStop) {
  SplatFrame s;
  for (int i = 0; i < 8; ++i)
    add_splat(s, {0, 0, 2.0f + 0.1f * i}, isotropic(0.05f), 0.9f,
              i < 4 ? std::array<float, 3>{1, 0, 0} : std::array<float, 3>{0, 0, 1});
  RenderOptions opt;
  opt.background = {0, 1, 0};
  const Image img = render(s, axis_camera(33, 33, 100), opt);
  const float* c = &img.rgb[3 * (16 * 33 + 16)];
  // The rule, evaluated independently in float with the splats' colour.
  float red[3];
  sh_color(0, &s.sh[0], 0, 0, 1, red);
  ASSERT_EQ(red[2], 0.0f);
  float T = 1, C = 0;
  int used = 0;
  for (int i = 0; i < 8; ++i) {
    const float test_T = T * (1 - 0.9f);
    if (test_T < 0.0001f) break;
    C += (i < 4 ? red[0] : 0.0f) * 0.9f * T;
    T = test_T;
    ++used;
  }
  EXPECT_EQ(used, 4);
  EXPECT_EQ(c[0], C);
  EXPECT_EQ(c[1], T);  // background green times the final transmittance
  EXPECT_EQ(c[2], 0.0f);
  EXPECT_NEAR(T, 1e-4f, 1e-9);
  EXPECT_GE(T, 1e-4f);
}

// Rotating the object (positions, covariances, sh_rotation = R) and the camera by the same R
// leaves the image unchanged up to float rounding; without sh_rotation it changes.
TEST(Render, ShRotationInvariance) {
  const SplatFrame base = random_scene(60, 3, 7, 3.0f, 4.0f);
  const Camera cam = axis_camera(96, 80, 90);
  const Image ref = render(base, cam);
  // A rotation by 0.7 rad about a tilted axis (Rodrigues), about the centre (0, 0, 3.5).
  double ax[3] = {0.3, -0.8, 0.5};
  const double an = std::sqrt(ax[0] * ax[0] + ax[1] * ax[1] + ax[2] * ax[2]);
  for (double& v : ax) v /= an;
  const double th = 0.7, ct = std::cos(th), st = std::sin(th);
  double R[9];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const double K[9] = {0, -ax[2], ax[1], ax[2], 0, -ax[0], -ax[1], ax[0], 0};
      R[3 * i + j] = (i == j ? ct : 0) + (1 - ct) * ax[i] * ax[j] + st * K[3 * i + j];
    }
  const double o[3] = {0, 0, 3.5};
  SplatFrame rot = base;
  rot.sh_rotation.clear();
  for (std::size_t i = 0; i < base.size(); ++i) {
    for (int a = 0; a < 3; ++a) {
      double v = o[a];
      for (int b = 0; b < 3; ++b) v += R[3 * a + b] * (base.position[3 * i + b] - o[b]);
      rot.position[3 * i + a] = float(v);
    }
    const float* c = &base.covariance[6 * i];
    const double S[9] = {c[0], c[1], c[2], c[1], c[3], c[4], c[2], c[4], c[5]};
    double RS[9], RSRt[9];
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) {
        RS[3 * a + b] = 0;
        for (int k = 0; k < 3; ++k) RS[3 * a + b] += R[3 * a + k] * S[3 * k + b];
      }
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) {
        RSRt[3 * a + b] = 0;
        for (int k = 0; k < 3; ++k) RSRt[3 * a + b] += RS[3 * a + k] * R[3 * b + k];
      }
    const int up[6] = {0, 1, 2, 4, 5, 8};
    for (int k = 0; k < 6; ++k) rot.covariance[6 * i + k] = float(RSRt[up[k]]);
    for (int k = 0; k < 9; ++k) rot.sh_rotation.push_back(float(R[k]));
  }
  Camera rcam = cam;
  for (int a = 0; a < 3; ++a) {
    double v = o[a];
    for (int b = 0; b < 3; ++b) v += R[3 * a + b] * (cam.position[b] - o[b]);
    rcam.position[a] = v;
    for (int b = 0; b < 3; ++b) {
      double m = 0;
      for (int k = 0; k < 3; ++k) m += R[3 * a + k] * cam.rotation[3 * k + b];
      rcam.rotation[3 * a + b] = m;
    }
  }
  const Image same = render(rot, rcam);
  // Float rounding of the rotated inputs (~1e-7 relative) perturbs pixel values by ~1e-6; the
  // discrete rules (alpha >= 1/255, integer radius, depth order) could flip at a rare pixel, so
  // the bound is on the mean and on nearly every channel, with a loose bound on the rest.
  std::size_t off = 0;
  double mean = 0;
  for (std::size_t i = 0; i < ref.rgb.size(); ++i) {
    const double d = std::fabs(double(ref.rgb[i]) - same.rgb[i]);
    mean += d;
    if (d > 1e-4) ++off;
  }
  mean /= double(ref.rgb.size());
  EXPECT_LT(mean, 2e-6);
  EXPECT_LE(off, ref.rgb.size() / 1000);
  EXPECT_LT(max_diff(ref, same), 0.02f);
  // The same rotated object without sh_rotation: the view-dependent colour is wrong.
  SplatFrame unrotated = rot;
  unrotated.sh_rotation.clear();
  EXPECT_GT(max_diff(ref, render(unrotated, rcam)), 0.05f);
}

// The tiled renderer equals the per-pixel brute-force reference bit for bit (SH 3, hundreds of
// splats, an image that is no multiple of the tile size), for any thread count.
TEST(Render, TiledEqualsBruteForce) {
  const SplatFrame s = random_scene(400, 3, 11, 1.5f, 6.0f);
  Camera cam = axis_camera(100, 70, 80);
  cam.position = {0.1, -0.05, -0.3};
  RenderOptions opt;
  opt.background = {0.2f, 0.4f, 0.6f};
  opt.threads = 1;
  const Image tiled = render(s, cam, opt);
  const Image brute = render_brute_force(s, cam, opt);
  EXPECT_TRUE(bitwise_equal(tiled, brute)) << "max diff " << max_diff(tiled, brute);
  opt.threads = 3;
  EXPECT_TRUE(bitwise_equal(tiled, render(s, cam, opt)));
  // The scene covers the image with overlapping splats (not a trivial comparison).
  std::size_t covered = 0;
  for (std::size_t i = 0; i < tiled.rgb.size(); i += 3)
    if (std::fabs(tiled.rgb[i] - 0.2f) > 0.05f) ++covered;
  EXPECT_GT(covered, tiled.rgb.size() / 3 / 3);
  // Listing the splats in another order changes nothing.
  SplatFrame reversed;
  for (std::size_t i = s.size(); i-- > 0;) copy_splat(s, i, reversed);
  EXPECT_TRUE(bitwise_equal(tiled, render(reversed, cam, opt)));
}

// The tile-local blend (each splat visiting only the pixels of its ellipse, the tile ending
// when every pixel is finished) against the previous blend, where every pixel walks its tile's
// whole list, and the radix sort against the comparison sort: the same image bit for bit, for
// scenes that stress the pixel cut (needle-thin and huge splats, grazing views, opacity above
// 1, exact depth ties) and that finish pixels early (dense stacks), at 1 and 3 threads.
TEST(Render, TileBlendEqualsLegacy) {
  std::vector<std::pair<std::string, SplatFrame>> scenes;
  scenes.emplace_back("mixed", random_scene(600, 3, 31, 1.0f, 6.0f));
  {
    // Needles: one scale 1e-4 of the others, so the screen conic is nearly singular and its
    // power cancels; plus a few splats filling the view.
    std::mt19937 rng(32);
    SplatFrame s;
    s.sh_degree = 0;
    std::uniform_real_distribution<float> u(-1, 1), z(1.5f, 4.0f), o(0.2f, 1.0f);
    for (int i = 0; i < 300; ++i) {
      const auto q = synthetic::random_quaternion(rng);
      const double big = i % 50 == 0 ? 2.0 : 0.3;
      const auto c = synthetic::covariance(q, {big, 1e-4 * big, 0.05 * big});
      add_splat(s, {u(rng), u(rng), z(rng)},
                {float(c[0]), float(c[1]), float(c[2]), float(c[3]), float(c[4]), float(c[5])},
                o(rng), {0.5f + 0.5f * u(rng), 0.5f + 0.5f * u(rng), 0.5f + 0.5f * u(rng)});
    }
    scenes.emplace_back("needles", s);
  }
  {
    // A dense stack in front (most pixels finish early), opacities above 1 (no cut), and
    // exact depth ties at z = 3.
    SplatFrame s = random_scene(500, 1, 33, 2.0f, 2.5f);
    for (std::size_t i = 0; i < s.size(); i += 7) s.opacity[i] = 1.5f;
    const SplatFrame tied = random_scene(60, 1, 34, 3.0f, 3.0f);
    for (std::size_t i = 0; i < tied.size(); ++i) copy_splat(tied, i, s);
    scenes.emplace_back("stack", s);
  }
  Camera cam = axis_camera(150, 90, 110);
  cam.position = {0.05, 0.1, -0.2};
  for (const auto& [name, s] : scenes) {
    RenderOptions opt;
    opt.background = {0.3f, 0.1f, 0.7f};
    opt.threads = 1;
    RenderStats stats;
    opt.stats = &stats;
    const Image fresh = render(s, cam, opt);
    opt.stats = nullptr;
    opt.legacy = true;
    const Image old = render(s, cam, opt);
    EXPECT_TRUE(bitwise_equal(fresh, old)) << name << " max diff " << max_diff(fresh, old);
    opt.legacy = false;
    opt.threads = 3;
    EXPECT_TRUE(bitwise_equal(fresh, render(s, cam, opt))) << name;
    // Not a trivial comparison: the splats cover tiles and change the image.
    EXPECT_GT(stats.tile_entries, 4 * s.size()) << name;
    EXPECT_GT(max_diff(fresh, render(SplatFrame{}, cam, opt)), 0.3f) << name;
  }
}

// render_distributed with the splats spread four different ways (blocks, round robin, all on
// the last rank, random), including splats of exactly equal depth: identical to the serial
// render bit for bit at every rank count.
TEST(RenderDistributed, IdenticalToSerial) {
  const MPI_Comm comm = MPI_COMM_WORLD;
  const int rank = rank_of(comm), ranks = size_of(comm);
  SplatFrame all = random_scene(3000, 3, 23, 1.0f, 8.0f);
  {
    // Equal depths: copies of splats moved sideways, and exact duplicates.
    const SplatFrame extra = random_scene(40, 3, 24, 2.0f, 2.0f);
    for (std::size_t i = 0; i < extra.size(); ++i) {
      copy_splat(extra, i, all);
      copy_splat(extra, i, all);
      all.position[all.position.size() - 3] += 0.05f;
      copy_splat(extra, i, all);
    }
  }
  Camera cam = axis_camera(161, 97, 70);
  RenderOptions opt;
  opt.background = {1, 1, 1};
  const Image serial = render(all, cam, opt);
  const std::size_t n = all.size();
  std::mt19937 rng(5);
  std::vector<int> random_owner(n);
  for (auto& r : random_owner) r = int(rng() % unsigned(ranks));
  for (int split = 0; split < 4; ++split) {
    SplatFrame local;
    local.sh_degree = all.sh_degree;
    for (std::size_t i = 0; i < n; ++i) {
      int owner = 0;
      if (split == 0) owner = int(i * std::size_t(ranks) / n);
      if (split == 1) owner = int(i % std::size_t(ranks));
      if (split == 2) owner = ranks - 1;
      if (split == 3) owner = random_owner[i];
      if (owner == rank) copy_splat(all, i, local);
    }
    RenderStats stats;
    opt.stats = &stats;
    const Image img = render_distributed(comm, local, cam, opt);
    if (rank == 0) {
      EXPECT_TRUE(bitwise_equal(img, serial))
          << "split " << split << " max diff " << max_diff(img, serial);
    } else {
      EXPECT_TRUE(img.rgb.empty());
    }
    opt.stats = nullptr;
  }
}

// --- cameras ----------------------------------------------------------------------------------

TEST(Camera, OrbitLooksAtTheCentre) {
  OrbitCamera orbit;
  orbit.center = {0.5, -1, 2};
  orbit.up = {0, 0, 2};  // normalised
  orbit.radius = 3;
  orbit.azimuth = 30;
  orbit.elevation = 25;
  orbit.d_azimuth = 10;
  orbit.width = 320;
  orbit.height = 200;
  orbit.fov_y_degrees = 50;
  for (long frame : {0L, 5L}) {
    const Camera c = orbit.at_frame(frame);
    const auto& R = c.rotation;
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) {
        double d = 0;
        for (int k = 0; k < 3; ++k) d += R[3 * k + a] * R[3 * k + b];
        EXPECT_NEAR(d, a == b ? 1 : 0, 1e-12);
      }
    const double det = R[0] * (R[4] * R[8] - R[5] * R[7]) - R[1] * (R[3] * R[8] - R[5] * R[6]) +
                       R[2] * (R[3] * R[7] - R[4] * R[6]);
    EXPECT_NEAR(det, 1, 1e-12);
    for (int a = 0; a < 3; ++a)  // forward (column 2) from the camera reaches the centre
      EXPECT_NEAR(c.position[a] + 3 * R[3 * a + 2], orbit.center[a], 1e-12);
    EXPECT_NEAR(R[3 * 2 + 0], 0, 1e-12);  // right is horizontal
    EXPECT_LT(R[3 * 2 + 1], 0);           // down points against up
    const double az = (30 + 10 * frame) * M_PI / 180, el = 25 * M_PI / 180;
    EXPECT_NEAR(c.position[0], 0.5 + 3 * std::cos(el) * std::cos(az), 1e-12);
    EXPECT_NEAR(c.position[1], -1 + 3 * std::cos(el) * std::sin(az), 1e-12);
    EXPECT_NEAR(c.position[2], 2 + 3 * std::sin(el), 1e-12);
    EXPECT_NEAR(c.fov_y() * 180 / M_PI, 50, 1e-12);
    EXPECT_NEAR(c.fov_x(), 2 * std::atan(320.0 / 200 * std::tan(25 * M_PI / 180)), 1e-12);
  }
  // Looking straight down the up axis still gives a proper frame.
  orbit.elevation = 90;
  orbit.up = {0, 1, 0};
  const Camera top = orbit.at_frame(0);
  for (double v : top.rotation) EXPECT_TRUE(std::isfinite(v));
  EXPECT_NEAR(top.rotation[3 * 1 + 2], -1, 1e-12);  // forward = -up
  orbit.up = {0, 0, 0};
  EXPECT_THROW(orbit.at_frame(0), InputError);
}

// An orbit camera around a splat draws it at the image centre.
TEST(Camera, OrbitRendersTheCentre) {
  SplatFrame s;
  add_splat(s, {1, 2, 3}, isotropic(0.05f), 0.9f, {1, 1, 1});
  OrbitCamera orbit;
  orbit.center = {1, 2, 3};
  orbit.radius = 2;
  orbit.azimuth = 70;
  orbit.width = orbit.height = 33;
  const Image img = render(s, orbit.at_frame(0));
  const auto peak = std::max_element(img.rgb.begin(), img.rgb.end()) - img.rgb.begin();
  EXPECT_EQ(peak / 3, 16 * 33 + 16);
}

TEST(Camera, CamerasJsonRoundTrip) {
  const fs::path dir = scratch("json_roundtrip");
  OrbitCamera orbit;
  orbit.d_azimuth = 37.1;
  orbit.up = {0.1, 0.2, 0.97};
  std::vector<Camera> cams;
  for (int i = 0; i < 3; ++i) cams.push_back(orbit.at_frame(i));
  cams[1].fx = 555.123456789012;
  const std::string path = (dir / "cameras.json").string();
  write_cameras_json(path, cams);
  const auto back = read_cameras_json(path);
  ASSERT_EQ(back.size(), cams.size());
  for (std::size_t i = 0; i < cams.size(); ++i) {
    EXPECT_EQ(back[i].width, cams[i].width);
    EXPECT_EQ(back[i].height, cams[i].height);
    EXPECT_EQ(back[i].fx, cams[i].fx);
    EXPECT_EQ(back[i].fy, cams[i].fy);
    EXPECT_EQ(back[i].position, cams[i].position);
    EXPECT_EQ(back[i].rotation, cams[i].rotation);
  }
  const Camera two = read_camera_spec(path + ":2");
  EXPECT_EQ(two.position, cams[2].position);
  EXPECT_EQ(read_camera_spec(path).position, cams[0].position);
  // No temporary left beside it.
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
}

//! The InputError message for reading `text` as cameras.json (empty when none is thrown).
std::string camera_error(const fs::path& dir, const std::string& name, const std::string& text,
                         const std::string& suffix = "") {
  const std::string path = (dir / name).string();
  std::ofstream(path) << text;
  try {
    read_camera_spec(path + suffix);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(Camera, BadCamerasJson) {
  const fs::path dir = scratch("json_bad");
  const std::string good_entry =
      "{\"id\": 0, \"img_name\": \"a\", \"width\": 64, \"height\": 48,\n"
      " \"position\": [0, 0, -3],\n \"rotation\": [[1, 0, 0], [0, 1, 0], [0, 0, 1]],\n"
      " \"fy\": 50, \"fx\": 50}";
  EXPECT_EQ(camera_error(dir, "ok.json", "[" + good_entry + "]"), "");
  auto with = [&](const std::string& from, const std::string& to) {
    std::string t = "[" + good_entry + ",\n" + good_entry + "]";
    const auto at = t.rfind(from);
    return t.replace(at, from.size(), to);
  };
  std::string e = camera_error(dir, "missing.json", with("\"fx\": 50", "\"fz\": 50"));
  EXPECT_NE(e.find("missing.json"), std::string::npos) << e;
  EXPECT_NE(e.find("entry 1"), std::string::npos) << e;
  EXPECT_NE(e.find("\"fx\""), std::string::npos) << e;
  e = camera_error(dir, "type.json", with("\"width\": 64", "\"width\": \"64\""));
  EXPECT_NE(e.find("type.json:5"), std::string::npos) << e;
  EXPECT_NE(e.find("\"width\""), std::string::npos) << e;
  e = camera_error(dir, "rows.json", with("[0, 0, 1]]", "[0, 0]]"));
  EXPECT_NE(e.find("rotation"), std::string::npos) << e;
  e = camera_error(dir, "notrot.json", with("[0, 0, 1]]", "[0, 0, 2]]"));
  EXPECT_NE(e.find("not a rotation"), std::string::npos) << e;
  e = camera_error(dir, "neg.json", with("\"fy\": 50", "\"fy\": -50"));
  EXPECT_NE(e.find("\"fy\""), std::string::npos) << e;
  e = camera_error(dir, "syntax.json", with("\"fy\": 50,", "\"fy\": 50,,"));
  EXPECT_NE(e.find("syntax.json:8"), std::string::npos) << e;
  e = camera_error(dir, "range.json", "[" + good_entry + "]", ":3");
  EXPECT_NE(e.find("range.json"), std::string::npos) << e;
  EXPECT_NE(e.find("out of range"), std::string::npos) << e;
  e = camera_error(dir, "object.json", good_entry);
  EXPECT_NE(e.find("array"), std::string::npos) << e;
  e = camera_error(dir, "nothere_dir/none.json", "");
  EXPECT_NE(e.find("none.json"), std::string::npos) << e;
}

// --- JSON -----------------------------------------------------------------------------------

TEST(Json, ParsesValues) {
  const JsonValue v = parse_json(
      "{\n \"a\": [1, -2.5e3, 0, 0.125, true, false, null],\n"
      " \"s\": \"q\\\"\\\\\\/\\b\\f\\n\\r\\t\\u00e9\\ud83d\\ude00\",\n \"o\": {\"x\": {}}, \"e\": "
      "[]}",
      "t.json");
  ASSERT_TRUE(v.is_object());
  const auto& a = v.find("a")->items();
  ASSERT_EQ(a.size(), 7u);
  EXPECT_EQ(a[1].as_number(), -2500.0);
  EXPECT_EQ(a[3].as_number(), 0.125);
  EXPECT_TRUE(a[4].as_bool());
  EXPECT_TRUE(a[6].is_null());
  EXPECT_EQ(a[0].line(), 2);
  EXPECT_EQ(v.find("s")->as_string(), "q\"\\/\b\f\n\r\t\xc3\xa9\xf0\x9f\x98\x80");
  EXPECT_EQ(v.find("o")->line(), 4);
  EXPECT_TRUE(v.find("o")->find("x")->is_object());
  EXPECT_EQ(v.find("missing"), nullptr);
  // dump and parse again: the same value, numbers exact.
  JsonValue w = JsonValue::object();
  w.set("pi", JsonValue::number(M_PI));
  w.set("tiny", JsonValue::number(-1.2345678901234567e-300));
  w.set("list", parse_json("[1, [2, {\"k\": \"v\"}]]", "x"));
  const JsonValue back = parse_json(w.dump(2), "dump");
  EXPECT_EQ(back.find("pi")->as_number(), M_PI);
  EXPECT_EQ(back.find("tiny")->as_number(), -1.2345678901234567e-300);
  EXPECT_EQ(back.dump(), w.dump());
}

TEST(Json, RejectsMalformedText) {
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"[1, 2,]", ":1:"},
      {"{\"a\": 1,\n}", ":2:"},
      {"[01]", "leading zero"},
      {"[1.]", "digit"},
      {"[-]", "digit"},
      {"[NaN]", "expected a value"},
      {"{\"a\" 1}", "':'"},
      {"{a: 1}", "double quotes"},
      {"[\"\\x\"]", "escape"},
      {"[\"a\nb\"]", ":1:"},
      {"[1] 2", "after"},
      {"", "end of file"},
      {"{\"k\": 1, \"k\": 2}", "duplicate key \"k\""},
      {"[\"\\ud800\"]", "surrogate"},
      {"[1e999]", "out of range"},
      {"// c\n[1]", "expected a value"},
      {std::string(600, '[') + std::string(600, ']'), "nesting"}};
  for (const auto& [text, fragment] : bad) {
    try {
      parse_json(text, "bad.json");
      ADD_FAILURE() << "accepted: " << text;
    } catch (const InputError& e) {
      const std::string msg = e.what();
      EXPECT_EQ(msg.rfind("bad.json:", 0), 0u) << msg;
      EXPECT_NE(msg.find(fragment), std::string::npos) << text << " -> " << msg;
    }
  }
}

// --- output -----------------------------------------------------------------------------------

TEST(Render, PngAndPsnr) {
  const fs::path dir = scratch("png");
  Image img;
  img.width = 3;
  img.height = 2;
  img.rgb = {0, 0.5f, 1, 2, -1, 0.25f, 0.1f, 0.2f, 0.3f, 1, 1, 1, 0, 0, 0, 0.999f, 0.001f, 0.5f};
  const std::string path = (dir / "img.png").string();
  write_image_png(path, img);
  const auto pic = test::load_png(path);
  ASSERT_EQ(pic.width, 3);
  ASSERT_EQ(pic.height, 2);
  EXPECT_EQ(pic.at(0, 0), (std::array<std::uint8_t, 3>{0, 128, 255}));
  EXPECT_EQ(pic.at(1, 0), (std::array<std::uint8_t, 3>{255, 0, 64}));
  EXPECT_EQ(pic.at(2, 1), (std::array<std::uint8_t, 3>{255, 0, 128}));
  Image other = img;
  EXPECT_TRUE(std::isinf(psnr(img, other)));
  for (float& v : other.rgb) v += 0.1f;
  EXPECT_NEAR(psnr(img, other), 20.0, 1e-4);  // mse 0.01
  other.width = 2;
  EXPECT_THROW(psnr(img, other), std::invalid_argument);
}

TEST(Video, MissingFramesOrFfmpeg) {
  const fs::path dir = scratch("video");
  EXPECT_THROW(assemble_mp4(dir.string(), 25, (dir / "v.mp4").string()), InputError);
  Image img;
  img.width = 17;
  img.height = 9;
  img.rgb.assign(17 * 9 * 3, 0.5f);
  write_image_png((dir / "a.png").string(), img);
  write_image_png((dir / "b.png").string(), img);
  const std::string mp4 = (dir / "v.mp4").string();
  if (find_ffmpeg().empty()) {
    EXPECT_EQ(assemble_mp4(dir.string(), 25, mp4), "");
    EXPECT_FALSE(fs::exists(mp4));
  } else {
    EXPECT_EQ(assemble_mp4(dir.string(), 25, mp4), mp4);
    EXPECT_GT(fs::file_size(mp4), 100u);
  }
  // Nothing else is left in the directory (no temporary, no frame list).
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()),
            find_ffmpeg().empty() ? 2 : 3);
}

}  // namespace
}  // namespace gen4d::gaussians
