// The renderer on a GPU (CUDA build with a device): the device's projection, binning and blend
// give the host's image up to float rounding, and the same image for any rank count and any
// order of the splats. Skipped without a device.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <vector>

#include "../drivers/SyntheticSplats.hpp"
#include "core/Device.hpp"
#include "gaussians/Render.hpp"

namespace gen4d::gaussians {
namespace {

//! `n` random splats of SH degree 3 in [-1, 1]^2 x [zlo, zhi], harmonics rotated by random
//! rotations (sh_rotation), and `ties` splats copied at a shared depth (exact depth ties).
SplatFrame scene(int n, unsigned seed, float zlo, float zhi, int ties) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1), z(zlo, zhi), o(0.05f, 0.999f), c(-1.5f, 1.5f);
  SplatFrame s;
  s.sh_degree = 3;
  for (int i = 0; i < n + ties; ++i) {
    const float depth = i < n ? z(rng) : 0.5f * (zlo + zhi);
    for (float v : {u(rng), u(rng), depth}) s.position.push_back(v);
    for (double v : synthetic::random_covariance(rng, 0.01, 0.12)) s.covariance.push_back(float(v));
    s.opacity.push_back(o(rng));
    for (int j = 0; j < 48; ++j) s.sh.push_back(c(rng) * (j < 3 ? 1.0f : 0.4f));
    for (double v : synthetic::quaternion_matrix(synthetic::random_quaternion(rng)))
      s.sh_rotation.push_back(float(v));
  }
  return s;
}

Camera camera(int w, int h) {
  Camera c;
  c.width = w;
  c.height = h;
  c.fx = c.fy = 0.8 * w;
  c.position = {0.1, -0.05, -0.3};
  return c;
}

bool bitwise_equal(const Image& a, const Image& b) {
  return a.width == b.width && a.height == b.height && a.rgb.size() == b.rgb.size() &&
         std::memcmp(a.rgb.data(), b.rgb.data(), a.rgb.size() * sizeof(float)) == 0;
}

// The GPU image against the host's. The device rounds differently (contracted multiply-adds
// unless built without them, its own exp), about 1e-6 of a value; where that flips one of the
// rasterizer's discrete rules (alpha >= 1/255, the 1e-4 stop, the integer radius) a pixel
// changes by at most one splat's weak contribution. So: the mean difference below 1e-5, at most
// 0.1 % of the values off by more than 1e-4, none by more than 0.02, and PSNR above 60 dB.
TEST(RenderGpu, DeviceMatchesHost) {
  if (!exec::use_device()) GTEST_SKIP() << "no CUDA device: " << exec::device_description();
  const SplatFrame s = scene(4000, 41, 1.0f, 6.0f, 30);
  const Camera cam = camera(283, 157);  // no multiple of the tile size
  RenderOptions opt;
  opt.background = {0.2f, 0.4f, 0.6f};
  opt.device = false;
  const Image host = render(s, cam, opt);
  opt.device = true;
  RenderStats stats;
  opt.stats = &stats;
  const Image gpu = render(s, cam, opt);
  ASSERT_EQ(gpu.width, host.width);
  ASSERT_EQ(gpu.height, host.height);
  EXPECT_GT(stats.tile_entries, s.size());
  double mean = 0, worst = 0;
  std::size_t off = 0, covered = 0;
  for (std::size_t i = 0; i < host.rgb.size(); ++i) {
    const double d = std::fabs(double(host.rgb[i]) - gpu.rgb[i]);
    mean += d;
    worst = std::max(worst, d);
    if (d > 1e-4) ++off;
    if (std::fabs(host.rgb[i] - opt.background[i % 3]) > 0.05f) ++covered;
  }
  mean /= double(host.rgb.size());
  std::printf("[ render gpu ] %s: mean |diff| %.3g, max %.3g, %zu of %zu values > 1e-4, %.1f dB\n",
              exec::device_description().c_str(), mean, worst, off, host.rgb.size(),
              psnr(host, gpu));
  EXPECT_GT(covered, host.rgb.size() / 3);  // the splats cover the image
  EXPECT_LT(mean, 1e-5);
  EXPECT_LE(off, host.rgb.size() / 1000);
  EXPECT_LT(worst, 0.02);
  EXPECT_GT(psnr(host, gpu), 60.0);
}

// On the device too the image does not depend on the order of the splats (equal keys are put
// in the canonical order) nor on how they are spread over the ranks: bit for bit.
TEST(RenderGpu, DeviceIndependentOfOrderAndRanks) {
  if (!exec::use_device()) GTEST_SKIP() << "no CUDA device: " << exec::device_description();
  const MPI_Comm comm = MPI_COMM_WORLD;
  int rank = 0, ranks = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &ranks);
  const SplatFrame all = scene(3000, 42, 1.0f, 8.0f, 200);
  const Camera cam = camera(161, 97);
  RenderOptions opt;
  opt.background = {1, 1, 1};
  const Image serial = render(all, cam, opt);
  // The splats listed backwards.
  SplatFrame reversed;
  reversed.sh_degree = all.sh_degree;
  const std::size_t n = all.size();
  for (std::size_t i = n; i-- > 0;) {
    reversed.position.insert(reversed.position.end(), &all.position[3 * i],
                             &all.position[3 * i] + 3);
    reversed.covariance.insert(reversed.covariance.end(), &all.covariance[6 * i],
                               &all.covariance[6 * i] + 6);
    reversed.opacity.push_back(all.opacity[i]);
    reversed.sh.insert(reversed.sh.end(), &all.sh[48 * i], &all.sh[48 * i] + 48);
    reversed.sh_rotation.insert(reversed.sh_rotation.end(), &all.sh_rotation[9 * i],
                                &all.sh_rotation[9 * i] + 9);
  }
  EXPECT_TRUE(bitwise_equal(serial, render(reversed, cam, opt)));
  // Round robin over the ranks.
  SplatFrame local;
  local.sh_degree = all.sh_degree;
  for (std::size_t i = static_cast<std::size_t>(rank); i < n;
       i += static_cast<std::size_t>(ranks)) {
    local.position.insert(local.position.end(), &all.position[3 * i], &all.position[3 * i] + 3);
    local.covariance.insert(local.covariance.end(), &all.covariance[6 * i],
                            &all.covariance[6 * i] + 6);
    local.opacity.push_back(all.opacity[i]);
    local.sh.insert(local.sh.end(), &all.sh[48 * i], &all.sh[48 * i] + 48);
    local.sh_rotation.insert(local.sh_rotation.end(), &all.sh_rotation[9 * i],
                             &all.sh_rotation[9 * i] + 9);
  }
  const Image img = render_distributed(comm, local, cam, opt);
  if (rank == 0) {
    EXPECT_TRUE(bitwise_equal(img, serial));
  } else {
    EXPECT_TRUE(img.rgb.empty());
  }
}

}  // namespace
}  // namespace gen4d::gaussians
