// Decks in runs: a curve-driven force ramp and its history, curves on tractions and kinematic
// motion, [[collider]] obstacles under the MPM, particles at the MPM grid walls.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "core/Deck.hpp"
#include "elastogen/Simulation.hpp"
#include "deck_test_util.hpp"
#include "elastogen_test_util.hpp"
#include "mpm/MpmSimulation.hpp"
#include "mpm_test_util.hpp"

namespace gen4d::test {
namespace {

//! A free jelly bar (no supports, no gravity, every node solid) pushed along z by a force on
//! all of it, ramped 0 -> 1 over 0.1 s by a [[curve]].
const std::string kRamp =
    TestDeck()
        .simulation(0.01, 0.2, {TestDeck::no_gravity()})
        .unpadded(0.05)
        .box({0, 0, 0}, {0.2, 0.1, 0.1})
        .material(1e5, 0.3, 1000)
        .table("[curve]", {{"name", quoted("ramp")}, {"time", "[0, 0.1]"}, {"factor", "[0, 1]"}})
        .table("[force]", {{"lo", "[-1, -1, -1]"},
                           {"hi", "[1, 1, 1]"},
                           {"force", "[0, 0, 3]"},
                           {"curve", quoted("ramp")}});

TEST(DeckRuns, CurveDrivenRampAppliesTheCurvesForceHistory) {
  const Config cfg = parse_deck(kRamp, "ramp.toml", ".");
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
  const double mass = 1000 * 0.2 * 0.1 * 0.1, F = 3.0, dt = cfg.dt;
  double momentum = 0;  // sum of dt F(t_n) over the steps taken: implicit Euler's impulse
  for (int n = 0; n < 15; ++n) {
    const double t = n * dt, ramp = std::min(t / 0.1, 1.0);
    const auto f = sim.dynamics().external_force(t);
    EXPECT_NEAR(f[2], F * ramp, 1e-12 * F) << "t = " << t;
    EXPECT_EQ(f[0], 0.0);
    EXPECT_EQ(f[1], 0.0);
    sim.dynamics().step(t);
    momentum += dt * f[2];
    // A uniform body force moves the bar rigidly: every node at the impulse's velocity.
    const auto v = gather_positions(sim, true);
    if (world_rank() != 0) continue;
    for (std::size_t i = 0; i < v.size(); i += 3) {
      ASSERT_NEAR(v[i + 2], momentum / mass, 1e-9 * momentum / mass + 1e-15) << "t = " << t;
      ASSERT_NEAR(v[i], 0.0, 1e-12);
    }
  }
  // Ten ramp steps of 0, 0.1, ..., 0.9 F, then five at F: a step load would give 15 F dt.
  EXPECT_NEAR(momentum, F * dt * (4.5 + 5), 1e-12);
}

TEST(DeckRuns, ConstantCurveLeavesTheRunBitForBit) {
  // A deck with a clamped, loaded bar under gravity, without a curve and with the constant 1.
  std::string deck = kRamp;
  deck.replace(deck.find("gravity = [0, 0, 0]"), 19, "gravity = [0, 0, -9.81]");
  deck.replace(deck.find("lo = [-1, -1, -1]"), 17, "lo = [0.15, -1, -1]");
  deck += "[[fixed]]\nlo = [-1, -1, -1]\nhi = [0.01, 1, 1]\n";
  std::string one = deck, none = deck;
  one.replace(one.find("time = [0, 0.1]\nfactor = [0, 1]"), 31, "time = [0]\nfactor = [1]");
  none.erase(none.find("curve = \"ramp\""), 14);
  none.erase(none.find("[[curve]]"), none.find("[[force]]") - none.find("[[curve]]"));
  std::vector<double> x[2];
  int k = 0;
  for (const std::string& text : {none, one}) {
    const Config cfg = parse_deck(text, "bar.toml", ".");
    elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
    for (int n = 0; n < 4; ++n) sim.dynamics().step(n * cfg.dt);
    x[k++] = gather_positions(sim);
  }
  EXPECT_EQ(x[0], x[1]);
  if (world_rank() == 0) EXPECT_FALSE(x[0].empty());
}

TEST(DeckRuns, CurvesScaleTractionsAndKinematicMotion) {
  std::string deck = kRamp;
  deck.replace(deck.find("[[force]]"), std::string::npos,
               "[[traction]]\nlo = [0.19, -1, -1]\nhi = [1, 1, 1]\ntraction = [0, 0, 100]\n"
               "pressure = 50\ncurve = \"ramp\"\n"
               "[[kinematic]]\nlo = [-1, -1, -1]\nhi = [0.01, 1, 1]\nvelocity = [0, 0.2, 0]\n"
               "curve = \"ramp\"\n");
  const Config cfg = parse_deck(deck, "traction.toml", ".");
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
  // The +x end face, 0.1 x 0.1 m: traction 1 N along z, pressure 0.5 N along -x, times ramp.
  for (const double t : {0.0, 0.03, 0.1, 0.15}) {
    const double ramp = std::min(t / 0.1, 1.0);
    const auto f = sim.dynamics().traction_force(t);
    EXPECT_NEAR(f[2], ramp * 1.0, 1e-12) << t;
    EXPECT_NEAR(f[0], -ramp * 0.5, 1e-12) << t;
  }
  // The clamp moves at velocity times the ramp: its offset is the ramp's integral.
  const KinematicConfig& k = cfg.kinematic[0];
  for (const double t : {0.05, 0.1, 0.3}) {
    const double integral = t <= 0.1 ? t * t / 0.2 : 0.05 + (t - 0.1);
    const auto p = elastogen::Elastodynamics::prescribed(k, {0, 0.05, 0.05}, t);
    EXPECT_NEAR(p[1], 0.05 + 0.2 * integral, 1e-15) << t;
    EXPECT_EQ(p[0], 0.0);
  }
}

//! A jelly cube falling at 2 m/s towards z = 0 in a grid box down to z = -0.5, with `obstacle`
//! appended.
std::string falling_cube(const std::string& obstacle) {
  return TestDeck()
             .simulation(0.005, 0.2)
             .mpm()
             .domain(0.05)
             .box({0, 0, 0.1}, {0.2, 0.2, 0.3})
             .material(2e5, 0.3, 1000, {{"model", quoted("fixed_corotated")}})
             .table("mpm", {{"lo", "[-0.3, -0.3, -0.5]"},
                            {"hi", "[0.5, 0.5, 0.8]"},
                            {"velocity", "[0, 0, -2]"}})
             .str() +
         obstacle;
}

struct Fall {
  double lowest = 1e300;    //!< lowest particle z of the run
  mpm::WallCount at_start;  //!< particles at the grid walls at rest
  mpm::WallCount most;      //!< at the substep with the most particles at the walls
};

Fall fall(const std::string& obstacle, double time) {
  const Config cfg = parse_deck(falling_cube(obstacle), "cube.toml", ".");
  mpm::MpmSimulation sim(MPI_COMM_WORLD, cfg);
  auto& s = sim.solver();
  Fall out;
  out.at_start = mpm::particles_at_walls(MPI_COMM_WORLD, s.spec(), 3, s.particles());
  for (double t = 0; t < time;) {
    const double dt = s.stable_dt(cfg.dt);
    s.substep(t, dt);
    t += dt;
    double low = 1e300;
    for (std::size_t i = 0; i < s.particles().size(); ++i)
      low = std::min(low, s.particles().x[3 * i + 2]);
    MPI_Allreduce(MPI_IN_PLACE, &low, 1, MPI_DOUBLE, MPI_MIN, MPI_COMM_WORLD);
    out.lowest = std::min(out.lowest, low);
    const auto walls = mpm::particles_at_walls(MPI_COMM_WORLD, s.spec(), 3, s.particles());
    if (walls.particles > out.most.particles) out.most = walls;
  }
  return out;
}

TEST(DeckRuns, MpmCollidersStopTheFallAndWallsHoldWhatPassesThrough) {
  const double dx = 0.05;
  // Without an obstacle the cube falls through z = 0 down to the grid's floor walls (its 3
  // lowest node layers, z <= -0.4), which hold it: particles within 3.5 cells of the floor.
  const Fall free = fall("", 0.2);
  EXPECT_LT(free.lowest, -0.35);
  EXPECT_EQ(free.at_start.particles, 0);
  EXPECT_GT(free.most.per_wall[4], 0);  // z-
  EXPECT_EQ(free.most.per_wall[5], 0);
  EXPECT_EQ(
      free.most.per_wall[0] + free.most.per_wall[1] + free.most.per_wall[2] + free.most.per_wall[3],
      0);
  EXPECT_EQ(free.most.particles, free.most.per_wall[4]);
  // A plane collider at z = 0 and a box anvil below z = 0 stop it there (grid contact: within
  // half a cell), and nothing reaches the walls.
  for (const char* obstacle :
       {"[[collider]]\ntype = \"plane\"\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\n",
        "[[collider]]\ntype = \"box\"\nlo = [-1, -1, -1]\nhi = [1, 1, 0]\n"}) {
    const Fall stopped = fall(obstacle, 0.2);
    EXPECT_GT(stopped.lowest, -0.5 * dx) << obstacle;
    EXPECT_LT(stopped.lowest, 0.05) << obstacle;  // it did fall onto it
    EXPECT_EQ(stopped.most.particles, 0) << obstacle;
  }
}

// [[curve]] on MPM boundary conditions: a particle translation ramped 0 -> 1 over 0.1 s sets
// the held particles' velocity to velocity * ramp(t) each substep; a moving cuboid travels
// velocity times the curve's integral.
TEST(DeckRuns, CurvesScaleMpmBoundaryConditions) {
  const std::string ramp =
      "[[curve]]\nname = \"ramp\"\ntime = [0, 0.1]\nfactor = [0, 1]\n"
      "[[boundary]]\ntype = \"enforce_particle_translation\"\nlo = [-1, -1, -1]\n"
      "hi = [1, 1, 1]\nvelocity = [0, 0, 1.5]\ncurve = \"ramp\"\n";
  const Config cfg = parse_deck(falling_cube(ramp), "cube.toml", ".");
  ASSERT_EQ(cfg.boundaries.size(), 1u);
  EXPECT_EQ(cfg.boundaries[0].curve.name(), "ramp");
  mpm::MpmSimulation sim(MPI_COMM_WORLD, cfg);
  auto& s = sim.solver();
  int checked = 0;
  for (double t = 0; t < 0.12;) {
    const double dt = s.stable_dt(cfg.dt);
    s.substep(t, dt);
    const double expected = 1.5 * std::min(1.0, t / 0.1);  // the factor at the substep's start
    for (std::size_t i = 0; i < s.particles().size(); ++i, ++checked)
      ASSERT_NEAR(s.particles().v[3 * i + 2], expected, 1e-12) << "t = " << t;
    t += dt;
  }
  EXPECT_GT(checked, 0);

  BoundaryConfig box;
  box.type = "cuboid";
  box.motion = "moving";
  box.velocity = {2, 0, 0};
  box.start = 0.05;
  box.end = 1;
  box.curve = cfg.boundaries[0].curve;
  // Over [0.05, 0.15] the ramp's integral is 0.5 * (0.1^2 - 0.05^2) / 0.1 + 0.05 = 0.0875.
  EXPECT_NEAR(mpm::cuboid_region(box, 0.15).lo[0] - box.region.lo[0], 2 * 0.0875, 1e-15);
  box.curve = Curve();  // no curve: velocity times the elapsed time, as before
  EXPECT_EQ(mpm::cuboid_region(box, 0.15).lo[0] - box.region.lo[0], 2 * (0.15 - 0.05));
}

}  // namespace
}  // namespace gen4d::test
