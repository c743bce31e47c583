// NeuralMtl::evaluate_device against NeuralMtl::evaluate: the same pass (NeuralMtlKernel.hpp)
// on the GPU and on the CPU, for a fitted network and random ones of other shapes, on batches
// with a partial last thread block.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "core/Device.hpp"
#include "neural/NeuralMtl.hpp"
#include "neural_test_util.hpp"
#if defined(GEN4D_CUDA)
#include "core/DeviceArray.hpp"
#endif

namespace gn = gen4d::neural;

TEST(NeuralMtlGpu, DeviceKernelMatchesTheCpuKernel) {
#if !defined(GEN4D_CUDA)
  GTEST_SKIP() << "built without CUDA";
#else
  if (!gen4d::exec::use_device())
    GTEST_SKIP() << "no CUDA device: " << gen4d::exec::device_description();
  std::vector<gn::NeuralMtlWeights> nets = {
      gn::read_weights(std::string(GEN4D_SOURCE_DIR) + "/inputs/models/mtl/neo_hookean_0.30.h5"),
      gen4d::test::random_weights(11, {24, 24}), gen4d::test::random_weights(12, {16, 20, 12}),
      gen4d::test::random_weights(13, {64, 5})};
  for (std::size_t k = 0; k < nets.size(); ++k) {
    const gn::NeuralMtl net(nets[k]);
    const std::size_t n = 10007;  // not a multiple of the 256-thread blocks
    const auto s = gen4d::test::random_sigmas(n, 20 + k);
    std::vector<double> psi(n), grad(3 * n), gpsi(n), ggrad(3 * n);
    net.evaluate(n, s.data(), psi.data(), grad.data());
    gen4d::exec::DeviceArray<double> ds, dpsi(n), dgrad(3 * n);
    ds.upload(s.data(), s.size());
    net.evaluate_device(n, ds.data(), dpsi.data(), dgrad.data());
    dpsi.download(gpsi.data(), n);
    dgrad.download(ggrad.data(), 3 * n);
    // Both sides round every operation of the same formulas; only the contraction of
    // multiply-adds differs, a few ulps per operation through the layers.
    for (std::size_t p = 0; p < n; ++p) {
      EXPECT_NEAR(gpsi[p], psi[p], 1e-12 * (1 + std::fabs(psi[p]))) << "net " << k << " " << p;
      for (int a = 0; a < 3; ++a)
        EXPECT_NEAR(ggrad[3 * p + a], grad[3 * p + a], 1e-12 * (1 + std::fabs(grad[3 * p + a])))
            << "net " << k << " point " << p;
    }
    // Gradient only (psi null).
    dgrad.zero();
    net.evaluate_device(n, ds.data(), nullptr, dgrad.data());
    dgrad.download(ggrad.data(), 3 * n);
    for (std::size_t i = 0; i < 3 * n; ++i)
      ASSERT_NEAR(ggrad[i], grad[i], 1e-12 * (1 + std::fabs(grad[i]))) << "net " << k << " " << i;
  }
#endif
}
