// ElastoGen's Jacobi sweep on a GPU (CUDA build with a device) against the host's: one sweep
// of the same JacobiSweepKernel from the same iterate. Skipped without a device.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "core/Device.hpp"
#include "elastogen/SweepDevice.hpp"
#include "elastogen_kernels_scene.hpp"

using namespace gen4d;

TEST(ElastogenKernelsGpu, OneDeviceSweepMatchesOneHostSweep) {
#if !defined(GEN4D_CUDA)
  GTEST_SKIP() << "built without the CUDA back end";
#else
  if (!exec::use_device()) GTEST_SKIP() << "no CUDA device: " << exec::device_description();
  test::KernelScene s = test::kernel_scene();
  elastogen::VoxelSystem& sys = *s.sys;
  const std::size_t n = s.d.size();
  const double omega = 0.67;
  std::vector<double> dh(n, 0.0), rh(n, 0.0), dg(n, 0.0), rg(n, 0.0);
  sys.jacobi_sweep(s.k, s.inv_dt2, omega, s.r.data(), s.diag.data(), s.d.data(), dh.data(),
                   rh.data());
  const auto kern =
      sys.jacobi_kernel(s.k, s.inv_dt2, omega, s.r.data(), s.diag.data(), sys.mass().data(),
                        sys.free_mask().data(), sys.adjacency().data(), nullptr, nullptr, nullptr);
  elastogen::DeviceJacobi gpu(kern, sys.ghosted().size());
  gpu.set(s.r.data(), s.d.data());
  gpu.sweep(1);
  gpu.get(dg.data(), rg.data());
  double worst_d = 0, worst_r = 0, scale_d = 0, scale_r = 0;
  elastogen::for_owned(sys.owned(), sys.ghosted(), [&](std::size_t nn, long, long, long) {
    for (int d = 0; d < 3; ++d) {
      const std::size_t q = 3 * nn + d;
      worst_d = std::max(worst_d, std::fabs(dg[q] - dh[q]));
      worst_r = std::max(worst_r, std::fabs(rg[q] - rh[q]));
      scale_d = std::max(scale_d, std::fabs(dh[q]));
      scale_r = std::max(scale_r, std::fabs(s.r[q]) + std::fabs(s.r[q] - rh[q]));  // r, A d
    }
  });
  std::printf(
      "[ elastogen gpu ] sweep: largest host-device difference %.3g (iterate), %.3g "
      "(residual)\n",
      worst_d, worst_r);
  // The same arithmetic in the same order; nvcc may contract a product and a sum into one
  // fused multiply-add, which moves a value by a few ulps of its largest term (the iterate;
  // r and A d for the residual, which cancels): 1e-12 of those scales.
  EXPECT_LE(worst_d, 1e-12 * scale_d);
  EXPECT_LE(worst_r, 1e-12 * scale_r);
#endif
}
