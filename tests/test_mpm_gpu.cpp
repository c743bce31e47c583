// MPM's kernels on a GPU (CUDA build with a device): P2G, the grid update and G2P launched on the
// device give the host's particle states. Skipped without a device.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "core/Device.hpp"
#include "mpm_test_util.hpp"
#include "mpm_threads_scene.hpp"

namespace gen4d {
namespace {

TEST(MpmGpu, DeviceKernelsMatchTheHost) {
  if (!exec::use_device()) GTEST_SKIP() << "no CUDA device: " << exec::device_description();
  for (const char* model : {"fixed_corotated", "drucker_prager"}) {
    auto host = test::kernel_scene(MPI_COMM_WORLD, model, false);
    auto gpu = test::kernel_scene(MPI_COMM_WORLD, model, true);
    ASSERT_FALSE(host->on_device());
    ASSERT_TRUE(gpu->on_device());
    double th = 0, tg = 0;
    test::run(*host, 30, th);
    test::run(*gpu, 30, tg);
    const auto a = test::gather_sorted(MPI_COMM_WORLD, host->particles());
    const auto b = test::gather_sorted(MPI_COMM_WORLD, gpu->particles());
    ASSERT_EQ(a.size(), b.size());
    // The device code is compiled without contracted multiply-adds and P2G's sums are exact, so
    // the states agree to rounding; the tolerance is 1e-12 of the scene's scale (m, m/s).
    double worst = 0;
    for (std::size_t i = 0; i < a.size(); ++i) worst = std::max(worst, std::abs(a[i] - b[i]));
    std::printf("[ mpm gpu ] %s: largest host-device difference %.3g\n", model, worst);
    EXPECT_LE(worst, 1e-12) << model;
  }
}

}  // namespace
}  // namespace gen4d
