//! The voxel forward model on box cells, attached masses and pre-loads: a thin cantilever strip
//! (two cells through its thickness, cells five times longer than thick) against Euler-Bernoulli
//! beam theory, with and without a tip mass, statically pre-loaded and released.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include "core/Deck.hpp"
#include "core/Error.hpp"
#include "forward/Model.hpp"

using namespace gen4d;
using namespace gen4d::forward;

namespace {

constexpr double kL = 0.5, kB = 0.05, kT = 0.002;  // m
constexpr double kE = 7e10, kRho = 2700;
const double kPi = std::acos(-1.0);

//! The strip clamped at x = 0, cells of hz = T / 2, hx = L / nx (5 hz by default), hy = B / ny
//! (nu = 0: a strip of any width is then an Euler-Bernoulli beam), with optional extra tables.
std::string strip_deck(const std::string& extra = "", double nu = 0.0, int nx = 100, int ny = 10) {
  const double hz = kT / 2;
  return fmt::format(R"(
[simulation]
dt = 0.0005
end_time = 0.2
gravity = [0.0, 0.0, 0.0]
[domain]
voxel_size = [{}, {}, {}]
padding = 1
[[geometry]]
type = "box"
lo = [0.0, 0.0, 0.0]
hi = [{}, {}, {}]
[material]
model = "fixed_corotated"
youngs_modulus = {}
poisson_ratio = {}
density = {}
[[fixed]]
lo = [-1.0, -1.0, -1.0]
hi = [1.0e-9, 1.0, 1.0]
{}
)",
                     kL / nx, kB / ny, hz, kL, kB, kT, kE, nu, kRho, extra);
}

//! Rayleigh damping as a run's terms (alpha, beta).
class Rayleigh : public TermSource {
 public:
  std::string name() const override { return "rayleigh"; }
  void add_terms(const std::vector<double>& v, ModelTerms& t) const override {
    t.rayleigh_alpha = v[0];
    t.rayleigh_beta = v[1];
  }
};

//! Euler-Bernoulli cantilever: omega_n = (beta_n L)^2 sqrt(EI / (rho A L^4)).
double beam_omega(double beta_l) {
  const double I = kB * kT * kT * kT / 12, A = kB * kT;
  return beta_l * beta_l * std::sqrt(kE * I / (kRho * A * std::pow(kL, 4)));
}

}  // namespace

TEST(ForwardThin, BoxCellsMatchEulerBernoulliFrequencies) {
  const VoxelModel m(parse_deck(strip_deck("", 0.0, 100, 4), "<strip>", "."));
  EXPECT_EQ(m.voxels(), 100u * 4u * 2u);
  const std::vector<double> w = m.rest_modes(m.nominal(), 2);
  ASSERT_EQ(w.size(), 2u);
  const double w1 = beam_omega(1.875104), w2 = beam_omega(4.694091);
  std::printf(
      "thin strip, hx = 5 hz, 2 cells through: f1 %.4f Hz (beam %.4f, %+.3f %%), "
      "f2 %.4f Hz (beam %.4f, %+.3f %%)\n",
      w[0] / (2 * kPi), w1 / (2 * kPi), 100 * (w[0] / w1 - 1), w[1] / (2 * kPi), w2 / (2 * kPi),
      100 * (w[1] / w2 - 1));
  EXPECT_NEAR(w[0] / w1, 1.0, 0.01);
  EXPECT_NEAR(w[1] / w2, 1.0, 0.01);
  // The trilinear element on the same cells locks in bending (far stiffer).
  Physics trilinear = m.nominal();
  trilinear.element = Element::trilinear;
  const std::vector<double> wt = m.rest_modes(trilinear, 1);
  ASSERT_EQ(wt.size(), 1u);
  EXPECT_GT(wt[0] / w1, 1.5);
}

TEST(ForwardThin, TipMassLowersTheFirstFrequencyAsBeamTheorySays) {
  // A point mass equal to the strip's own mass over the last 5 mm: beta_1 L = 1.2479 (the
  // cantilever with a tip mass ratio of 1, no rotary inertia).
  const double m_strip = kRho * kL * kB * kT;
  const VoxelModel m(parse_deck(strip_deck(fmt::format(R"(
[[point_mass]]
lo = [0.4999, -1.0, -1.0]
hi = [1.0, 1.0, 1.0]
mass = {}
)",
                                                       m_strip),
                                           0.0, 50, 4),
                                "<strip>", "."));
  const std::vector<double> w = m.rest_modes(m.nominal(), 1);
  ASSERT_EQ(w.size(), 1u);
  const double w1 = beam_omega(1.2479);
  std::printf("tip mass = strip mass: f1 %.4f Hz (beam %.4f, %+.3f %%)\n", w[0] / (2 * kPi),
              w1 / (2 * kPi), 100 * (w[0] / w1 - 1));
  EXPECT_NEAR(w[0] / w1, 1.0, 0.01);
}

TEST(ForwardThin, PreloadStartsFromTheStaticDeflectionAndRingsAboutRest) {
  // 0.5 N on the tip, held before t = 0 and released at t = 0: frame 0 is the static
  // deflection F L^3 / (3 E I); the tip then swings to about -that and back.
  const double F = 0.5;
  const VoxelModel m(parse_deck(strip_deck(fmt::format(R"(
[[force]]
lo = [0.4999, -1.0, -1.0]
hi = [1.0, 1.0, 1.0]
force = [0.0, 0.0, {}]
start = -1.0
end = 0.0
)",
                                                       F),
                                           0.0, 50, 4),
                                "<strip>", "."));
  std::vector<ChannelRequest> req(2);
  req[0].at = m.attach({kL, kB / 2, kT / 2});
  req[1].at = req[0].at;
  req[1].acceleration = true;
  const double period = 2 * kPi / beam_omega(1.875104);
  for (double t = 0; t <= 0.6 * period; t += 0.001) req[0].t.push_back(t), req[1].t.push_back(t);
  Physics ph = m.nominal();
  const auto t0 = std::chrono::steady_clock::now();
  const Trace tr = m.run(ph, req);
  ASSERT_TRUE(tr.ok) << tr.failure;
  std::printf(
      "run: %ld steps, %ld Newton iterations, %ld factorizations, %ld restarts; %.3f s "
      "(internal %.3f, tangent %.3f, factor %.3f, solve %.3f)\n",
      tr.steps, tr.newton_iterations, tr.factorizations, tr.restarts,
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(),
      tr.time_internal, tr.time_tangent, tr.time_factor, tr.time_solve);
  const double I = kB * kT * kT * kT / 12, delta = F * kL * kL * kL / (3 * kE * I);
  const double z0 = tr.channel[0][2] - kT / 2;
  double zmin = 1e300;
  for (std::size_t k = 0; k < req[0].t.size(); ++k)
    zmin = std::min(zmin, tr.channel[0][3 * k + 2] - kT / 2);
  std::printf("pre-load: static tip deflection %.6g m (beam %.6g, %+.3f %%), swing to %.6g m\n", z0,
              delta, 100 * (z0 / delta - 1), zmin);
  EXPECT_NEAR(z0 / delta, 1.0, 0.01);
  EXPECT_NEAR(zmin / z0, -1.0, 0.05);
  // Released at t = 0: the acceleration there pulls back towards rest; before it, none.
  EXPECT_LT(tr.channel[1][2], 0.0);
  ph.time_offset = -0.01;  // the recording's t = 0 is 10 ms before the release
  const Trace early = m.run(ph, req);
  ASSERT_TRUE(early.ok);
  EXPECT_EQ(early.channel[1][2], 0.0);
  EXPECT_EQ(early.channel[0][2], tr.channel[0][2]);  // at rest, pre-loaded
}

TEST(ForwardThin, PointMassRegionWithoutNodesIsAnInputError) {
  const std::string deck = strip_deck(R"(
[[point_mass]]
lo = [2.0, 2.0, 2.0]
hi = [3.0, 3.0, 3.0]
mass = 0.1
)");
  try {
    const VoxelModel m(parse_deck(deck, "strip.toml", "."));
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("point_mass"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("strip.toml"), std::string::npos) << e.what();
  }
}

TEST(ForwardThin, StripPlainDeckRunsLinearInOneSolveAStep) {
  // inputs/strip_plain.toml (50 x 4 x 2 box cells, the linear law, a point mass, a pre-load):
  // the linear law's tangent is the rest stiffness, so each step takes one solve, which is the
  // step's solution: iterating to the Newton tolerance changes the samples by rounding only.
  // A 6 s run's time is in drivers/bench (bench_diagnose --deck inputs/strip_plain.toml).
  const VoxelModel m(load_deck(std::string(GEN4D_SOURCE_DIR) + "/inputs/strip_plain.toml", {}));
  EXPECT_EQ(m.voxels(), 50u * 4u * 2u);
  std::vector<ChannelRequest> req(1);
  req[0].at = m.attach({0.44, 0.0254, 0.002032});
  req[0].acceleration = true;
  for (int k = 0; k < 100; ++k) req[0].t.push_back(0.002 * k);
  Physics ph = m.nominal();
  ph.release_duration = 0.002;
  const Trace tr = m.run(ph, req);
  ASSERT_TRUE(tr.ok) << tr.failure;
  EXPECT_LE(tr.newton_iterations, tr.steps + 4);  // and a few for the static pre-load
  EXPECT_EQ(tr.restarts, 0);
  // The two agree to the solve's conditioning error (~1e-10 of the motion on this thin strip):
  // in position to 1 % of the Newton tolerance (1e-5 cell edges, what iterating guarantees);
  // in acceleration, which the trapezoidal rule reads from positions times 4 / dt^2, to 1e-6
  // of its peak (1e-3 of the recording's noise).
  // With Rayleigh damping (modal damping ~0.4 %), whose stress is linear under the linear law.
  const Rayleigh rayleigh;
  ph.effects.push_back({&rayleigh, {0.1, 3e-5}});
  Physics iterated = ph;
  iterated.linear_single_solve = false;
  std::vector<ChannelRequest> both = req;
  both.push_back(req[0]);
  both[1].acceleration = false;
  const Trace one = m.run(ph, both), check = m.run(iterated, both);
  ASSERT_TRUE(one.ok && check.ok) << one.failure << check.failure;
  EXPECT_LE(one.newton_iterations, one.steps + 4);
  EXPECT_GE(check.newton_iterations, 2 * check.steps);
  for (std::size_t c = 0; c < 2; ++c) {
    double peak = 0, diff = 0;
    for (std::size_t k = 2; k < one.channel[c].size(); k += 3) {  // the z components
      const double rest = c == 1 ? 0.002032 : 0.0;
      peak = std::max(peak, std::abs(check.channel[c][k] - rest));
      diff = std::max(diff, std::abs(one.channel[c][k] - check.channel[c][k]));
    }
    EXPECT_GT(peak, c == 0 ? 1.0 : 1e-3);
    const double bound = c == 0 ? 1e-6 * peak : 0.01 * ph.newton_tolerance * 0.001016;
    EXPECT_LT(diff, bound) << (c == 0 ? "acceleration" : "position");
  }
  // Released towards -z: the sensor accelerates along -z first.
  EXPECT_LT(tr.channel[0][3 * 2 + 2], -1.0);
  // Before the release (the recording starts 5 ms early) the sensor reads nothing.
  ph.time_offset = -0.005;
  const Trace early = m.run(ph, req);
  ASSERT_TRUE(early.ok);
  EXPECT_EQ(early.channel[0][2], 0.0);
  EXPECT_EQ(early.channel[0][5], 0.0);
  EXPECT_LT(early.channel[0][3 * 5 + 2], -1.0);
}
