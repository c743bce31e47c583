// The diagnose model's von Mises return map (HenckyJ2, eigen-decomposition of b = Fe Fe^T)
// against the MPM von_mises material (Jacobi SVD of Fe) with the same constants: elastic and
// plastic trial states, small and large strains, near-degenerate principal stretches.
#include <gtest/gtest.h>

#include <random>

#include "forward/HenckyJ2.hpp"
#include "mpm/Material.hpp"

namespace gen4d::forward {
namespace {

TEST(HenckyJ2, MatchesTheMpmVonMisesMaterial) {
  const double E = 5e5, nu = 0.3, sy = 2e4, H = 3e4;
  mpm::MaterialParams mp;
  mp.model = "von_mises";
  mp.source = "test";
  mp.values = {{"youngs_modulus", E},
               {"poisson_ratio", nu},
               {"density", 1000.0},
               {"yield_stress", sy},
               {"hardening", H}};
  const auto vm = mpm::make_material(mp);
  HenckyJ2 j2;
  j2.mu = E / (2 * (1 + nu));
  j2.lambda = E * nu / ((1 + nu) * (1 - 2 * nu));
  j2.yield_stress = sy;
  j2.hardening = H;
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(-1, 1);
  int plastic = 0;
  for (int k = 0; k < 400; ++k) {
    const double amp = k < 100 ? 1e-3 : k < 200 ? 1e-6 : k < 300 ? 0.05 : 0.3;
    double F[9];
    for (int i = 0; i < 9; ++i) F[i] = (i % 4 == 0 ? 1.0 : 0.0) + amp * u(rng);
    double state[mpm::kStateSize];
    vm->init_state(state);
    state[0] = k % 3 == 0 ? 0.0 : 0.01 * (1 + u(rng));
    double eps = state[0];
    const double eps0 = eps;
    double Fa[9], Fb[9], ta[9], tb[9];
    std::copy(F, F + 9, Fa);
    std::copy(F, F + 9, Fb);
    vm->update(1, Fa, state, ta, 1e-3);
    ASSERT_TRUE(j2.update(Fb, eps, tb));
    double tscale = 1e-300;
    for (int i = 0; i < 9; ++i) tscale = std::max(tscale, std::abs(ta[i]));
    for (int i = 0; i < 9; ++i) {
      EXPECT_NEAR(tb[i], ta[i], 1e-9 * tscale + 1e-9) << "case " << k << " entry " << i;
      EXPECT_NEAR(Fb[i], Fa[i], 1e-11) << "case " << k << " entry " << i;
    }
    EXPECT_NEAR(eps, state[0], 1e-12) << "case " << k;
    plastic += state[0] > eps0;
  }
  EXPECT_GT(plastic, 50);  // both branches are exercised
  EXPECT_LT(plastic, 350);
}

TEST(HenckyJ2, RejectsASingularDeformation) {
  HenckyJ2 j2;
  j2.mu = 1e5;
  j2.lambda = 1e5;
  j2.yield_stress = 1e3;
  double Fe[9] = {1, 0, 0, 0, 1, 0, 0, 0, 0}, eps = 0, tau[9];
  EXPECT_FALSE(j2.update(Fe, eps, tau));
}

}  // namespace
}  // namespace gen4d::forward
