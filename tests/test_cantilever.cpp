// Static cantilever under a small tip load vs Euler-Bernoulli: delta = F L^3 / (3 E I).
//
// Resolution: a 0.4 x 0.04 x 0.04 m beam (L/H = 10) with h = H/4 (40 x 4 x 4 voxels).
// Poisson ratio 0 so the 3D clamp adds no anticlastic stiffening; the load is small
// (tip deflection ~ 0.3% of L), so the corotated solution is the linear one. A time step of
// 1e4 s makes the inertia term negligible: one implicit-Euler step from rest is the static
// solve. The remaining gap to beam theory is the trilinear voxel's parasitic shear
// (which stiffens) and Timoshenko shear (which softens, ~0.6% here); 5% bounds both at this
// resolution and the test prints the measured error (-2.5 %).
//
// Relaxation: CG, because a static solve (dt -> infinity) has no mass term and damped Jacobi
// needs O(condition number) sweeps. The outer (local-global) loop converges linearly and
// slowly for bending, whose strain is small next to its rotation: ~12.5k plain loops here,
// ~3.3k with the default Anderson acceleration (depth 5); the
// accuracy check, not a loop cap, decides when it is done.
#include <gtest/gtest.h>

#include <cmath>

#include "deck_test_util.hpp"
#include "elastogen_test_util.hpp"

using namespace gen4d;

namespace {
Config cantilever_deck(const std::string& variant) {
  const bool newton = variant == "newton";
  const std::string relaxation = newton ? "cg" : variant;
  BeamDeck beam = test::slender_beam();
  beam.dt = beam.end_time = 1.0e4;
  beam.solver.set("relaxation", relaxation)
      .set("max_sweeps", 20000)
      .set("inner_tolerance", 1e-4)
      .set("max_outer", 20000)
      .set("max_extra_outer", 20000)
      .set("outer_tolerance", 1e-6)
      .set("accuracy_tolerance", 1e-3);
  const std::string deck = test::with_tip_load(beam.text());
  return parse_deck(deck, "<cantilever>", ".",
                    {std::string("solver.method=") + (newton ? "newton" : "elastogen")});
}

double tip_deflection(elastogen::Simulation& sim) {
  const auto x = test::gather_positions(sim);
  if (test::world_rank() != 0) return 0;
  const auto& dims = sim.grid().global_nodes();
  double sum = 0;
  int n = 0;
  const long i = dims[0] - 1;
  for (long k = 0; k < dims[2]; ++k)
    for (long j = 0; j < dims[1]; ++j) {
      const double z0 = 0.01 * k;
      sum += x[3 * ((k * dims[1] + j) * dims[0] + i) + 2] - z0;
      ++n;
    }
  return -sum / n;
}
}  // namespace

class Cantilever : public ::testing::TestWithParam<std::string> {};

TEST_P(Cantilever, StaticTipDeflectionMatchesEulerBernoulli) {
  const Config cfg = cantilever_deck(GetParam());
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
  const auto st = sim.dynamics().step(0.0);
  EXPECT_TRUE(st.accurate) << "accuracy " << st.accuracy;
  const double delta = tip_deflection(sim);
  if (test::world_rank() == 0) {
    const double L = 0.4, H = 0.04, E = 1.0e6, F = 0.01;
    const double I = H * H * H * H / 12.0;
    const double eb = F * L * L * L / (3.0 * E * I);
    const double err = (delta - eb) / eb;
    std::printf(
        "[cantilever %s] tip deflection %.6e m, Euler-Bernoulli %.6e m, error %+.2f %%, "
        "%d loops, %ld sweeps, residual %.1e\n",
        GetParam().c_str(), delta, eb, 100 * err, st.outer, st.sweeps, st.accuracy);
    EXPECT_LT(std::fabs(err), 0.05);
  }
}

// "newton" is the reference solver (PETSc SNES) on the same voxels and energy.
INSTANTIATE_TEST_SUITE_P(Relaxations, Cantilever, ::testing::Values("cg", "newton"));
