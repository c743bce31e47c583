// Several materials in one deck ([[material]] entries bound to named parts or boxes): the deck's
// checks, the slot and mass of every particle or voxel, each slot updated by its own material,
// and the MPM scenes of the issue (a jelly ball in a sand pile, a metal plate under a paste)
// bit-identical at 1, 2 and 4 ranks; the voxel solver with a stiff and a soft half.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "core/Deck.hpp"
#include "core/Error.hpp"
#include "elastogen/Simulation.hpp"
#include "deck_test_util.hpp"
#include "elastogen_test_util.hpp"
#include "mpm_test_util.hpp"
#include "mpm/MaterialSet.hpp"
#include "mpm/MpmSimulation.hpp"

namespace gen4d {
namespace {

// A sand pile with a jelly ball falling into it: the ball is the part named "ball".
const std::string kSandAndBall =
    test::TestDeck()
        .simulation(2e-3, 0.1)
        .domain(0.05)
        .table("[geometry]", {{"type", test::quoted("box")},
                              {"name", test::quoted("pile")},
                              {"lo", "[0, 0, 0]"},
                              {"hi", "[0.4, 0.3, 0.15]"}})
        .table("[geometry]", {{"type", test::quoted("sphere")},
                              {"name", test::quoted("ball")},
                              {"center", "[0.2, 0.15, 0.3]"},
                              {"radius", "0.08"}})
        .table("[material]", {{"model", test::quoted("drucker_prager")},
                              {"youngs_modulus", "2e5"},
                              {"poisson_ratio", "0.3"},
                              {"density", "1600"},
                              {"friction_angle", "35"}})
        .table("[material]", {{"geometry", test::quoted("ball")},
                              {"model", test::quoted("fixed_corotated")},
                              {"youngs_modulus", "5e4"},
                              {"poisson_ratio", "0.35"},
                              {"density", "1000"}})
        .mpm()
        .table(
            "mpm",
            {{"lo", "[-0.2, -0.2, -0.2]"}, {"hi", "[0.6, 0.5, 0.6]"}, {"velocity", "[0, 0, -0.5]"}})
        .table("[boundary]", {{"type", test::quoted("surface_collider")},
                              {"point", "[0, 0, 0]"},
                              {"normal", "[0, 0, 1]"},
                              {"surface", test::quoted("sticky")}});

// A paste on a metal plate: the plate is a box of rest positions, the rest paste.
const std::string kPasteOnPlate =
    test::TestDeck()
        .simulation(2e-3, 0.1)
        .domain(0.05)
        .box({0, 0, 0}, {0.4, 0.3, 0.3})
        .table("[material]", {{"model", test::quoted("herschel_bulkley")},
                              {"youngs_modulus", "1e5"},
                              {"poisson_ratio", "0.3"},
                              {"density", "1200"},
                              {"yield_stress", "40"},
                              {"consistency", "1"}})
        .region("material", {-1, -1, -1}, {1, 1, 0.076},
                {{"model", test::quoted("von_mises")},
                 {"youngs_modulus", "2e6"},
                 {"poisson_ratio", "0.3"},
                 {"density", "7800"},
                 {"yield_stress", "1e5"}})
        .mpm()
        .table("mpm", {{"lo", "[-0.2, -0.2, -0.2]"}, {"hi", "[0.6, 0.5, 0.5]"}})
        .table("[boundary]", {{"type", test::quoted("surface_collider")},
                              {"point", "[0, 0, 0]"},
                              {"normal", "[0, 0, 1]"},
                              {"surface", test::quoted("separate")},
                              {"friction", "0.3"}});

Config deck(const std::string& text, const std::vector<std::string>& sets = {}) {
  return parse_deck(text, "<multi>", ".", sets);
}

void expect_input_error(const std::string& text, const std::vector<std::string>& sets,
                        const std::string& expected) {
  try {
    deck(text, sets);
    ADD_FAILURE() << "no InputError, expected: " << expected;
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
  }
}

TEST(MultiMaterialDeck, EntriesBindToNamedPartsAndBoxes) {
  const Config a = deck(kSandAndBall);
  EXPECT_EQ(a.material.model, "drucker_prager");
  ASSERT_EQ(a.material_regions.size(), 1u);
  EXPECT_EQ(a.material_regions[0].geometry_part, 1);
  EXPECT_EQ(material_slot(a, 1, {0.2, 0.15, 0.3}), 1);
  EXPECT_EQ(material_slot(a, 0, {0.2, 0.15, 0.3}), 0);
  const Config b = deck(kPasteOnPlate);
  ASSERT_EQ(b.material_regions.size(), 1u);
  EXPECT_TRUE(b.material_regions[0].has_region);
  EXPECT_EQ(material_slot(b, 0, {0.1, 0.1, 0.05}), 1);
  EXPECT_EQ(material_slot(b, 0, {0.1, 0.1, 0.2}), 0);
  // --set reaches an entry by index, and the deck text round-trips as [[material]].
  const Config c = deck(kSandAndBall, {"material.1.youngs_modulus=7e4"});
  EXPECT_EQ(c.material_regions[0].youngs_modulus, 7e4);
  const Config d = parse_deck(c.text, "<again>", ".");
  EXPECT_EQ(d.material_regions.size(), 1u);
  EXPECT_EQ(d.material_regions[0].youngs_modulus, 7e4);
}

TEST(MultiMaterialDeck, BadEntriesNameTheKey) {
  const std::string ball = kSandAndBall;
  auto replaced = [&](const std::string& from, const std::string& to) {
    std::string s = ball;
    s.replace(s.find(from), from.size(), to);
    return s;
  };
  expect_input_error(replaced("geometry = \"ball\"", "geometry = \"bal\"").c_str(), {},
                     "no [[geometry]] part is named 'bal' (named parts: 'pile', 'ball')");
  expect_input_error(replaced("geometry = \"ball\"\n", "").c_str(), {}, "needs a binding");
  expect_input_error(replaced("geometry = \"ball\"", "geometry = \"ball\"\nlo = [0, 0, 0]").c_str(),
                     {}, "not both");
  expect_input_error(
      replaced("[[material]]\nmodel = \"drucker", "[[material]]\nlo = [0, 0, 0]\nmodel = \"drucker")
          .c_str(),
      {}, "the first [[material]] is the material of everything");
  expect_input_error(replaced("name = \"pile\"", "name = \"ball\"").c_str(), {},
                     "'ball' already names geometry.0");
  expect_input_error(kSandAndBall, {"material.youngs_modulus=1"}, "address one as material.INDEX");
  // The voxel solver needs one law and target, and not the Newton reference.
  const std::string voxel =
      test::TestDeck()
          .simulation(0.01, 0.02)
          .domain(0.05)
          .box({0, 0, 0}, {0.2, 0.1, 0.1})
          .table("[material]",
                 {{"youngs_modulus", "1e5"}, {"poisson_ratio", "0.3"}, {"density", "1000"}})
          .region("material", {0.1, -1, -1}, {1, 1, 1},
                  {{"model", test::quoted("neo_hookean")},
                   {"youngs_modulus", "1e6"},
                   {"poisson_ratio", "0.3"},
                   {"density", "1000"}});
  expect_input_error(voxel.c_str(), {}, "needs one law for every [[material]]");
  expect_input_error(voxel.c_str(), {"material.1.model=corotated", "solver.method=newton"},
                     "Newton reference takes one material");
}

TEST(MaterialSet, EachRunOfSlotsIsUpdatedByItsOwnMaterial) {
  const Config cfg = deck(kPasteOnPlate);
  const mpm::MaterialSet set = mpm::make_deck_materials(cfg);
  ASSERT_EQ(set.size(), 2u);
  EXPECT_EQ(set.describe(), "herschel_bulkley + von_mises");
  // Twelve particles, slots mixed in runs, each with a distinct sheared F.
  const std::vector<std::uint8_t> slot{0, 0, 1, 1, 1, 0, 1, 0, 0, 0, 1, 1};
  const std::size_t n = slot.size();
  std::vector<double> F(9 * n), state(mpm::kStateSize * n, 0.0), tau(9 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const double g = 0.02 * static_cast<double>(i + 1);
    const double f[9] = {1 + g, 0.5 * g, 0, 0.1 * g, 1 - 0.3 * g, 0.2 * g, 0, 0, 1 + 0.1 * g};
    std::copy_n(f, 9, &F[9 * i]);
    set[slot[i]].init_state(&state[mpm::kStateSize * i]);
  }
  std::vector<double> F2 = F, state2 = state, tau2(9 * n);
  set.update(n, slot.data(), F.data(), state.data(), tau.data(), 1e-3);
  // The same particles one at a time through their own material.
  for (std::size_t i = 0; i < n; ++i)
    set[slot[i]].update(1, &F2[9 * i], &state2[mpm::kStateSize * i], &tau2[9 * i], 1e-3);
  EXPECT_EQ(F, F2);
  EXPECT_EQ(state, state2);
  EXPECT_EQ(tau, tau2);
  // And the two materials really differ on the same F.
  double a[9], b[9];
  set[0].stress(1, &F2[0], &state2[0], a);
  set[1].stress(1, &F2[0], &state2[0], b);
  EXPECT_GT(std::abs(b[1] - a[1]), 10 * std::abs(a[1]));
}

// Particles::pack's record: id, x (3), v (3), C (9), F (9), state, mass, volume, flag, slot.
constexpr int kV = 4, kMass = 25 + mpm::kStateSize, kSlot = 28 + mpm::kStateSize;

std::vector<double> run_scene(MPI_Comm comm, const Config& cfg, int substeps) {
  mpm::MpmSimulation sim(comm, cfg);
  double t = 0;
  for (int k = 0; k < substeps; ++k) {
    const double dt = sim.solver().stable_dt(cfg.dt);
    sim.solver().substep(t, dt);
    t += dt;
  }
  return test::gather_sorted(comm, sim.solver().particles());
}

//! Slots and masses as the deck says, and the scene bit-identical on MPI_COMM_WORLD and on one
//! rank.
void expect_scene(const std::string& text, double density0, double density1, long expected_slot1) {
  const Config cfg = deck(text);
  constexpr int W = mpm::Particles::kRecord;
  const std::vector<double> dist = run_scene(MPI_COMM_WORLD, cfg, 25);
  if (test::world_rank() != 0) return;
  const std::vector<double> serial = run_scene(MPI_COMM_SELF, cfg, 25);
  ASSERT_EQ(dist.size(), serial.size());
  long differ = 0;
  for (std::size_t i = 0; i < dist.size(); ++i) differ += dist[i] != serial[i];
  EXPECT_EQ(differ, 0);
  long slot1 = 0;
  double moved = 0;
  for (std::size_t i = 0; i < serial.size(); i += W) {
    slot1 += serial[i + kSlot] == 1;
    for (int d = 0; d < 3; ++d) moved = std::max(moved, std::abs(serial[i + kV + d]));
  }
  EXPECT_EQ(slot1, expected_slot1);
  EXPECT_GT(moved, 1e-2);  // the scene really moves
  // Mass = density x rest volume: the ratio of a slot-1 to a slot-0 particle of the same
  // lattice volume is the density ratio.
  double m0 = 0, m1 = 0;
  for (std::size_t i = 0; i < serial.size(); i += W)
    (serial[i + kSlot] == 0 ? m0 : m1) = serial[i + kMass];
  EXPECT_DOUBLE_EQ(m1 / m0, density1 / density0);
}

TEST(MultiMaterialMpm, JellyBallInASandPileIsBitIdenticalAcrossRankCounts) {
  // The ball's lattice points: 8 per cell of 0.05 m inside the sphere of radius 0.08.
  const Config cfg = deck(kSandAndBall);
  mpm::MpmSimulation probe(MPI_COMM_SELF, cfg);
  long ball = 0;
  for (std::size_t i = 0; i < probe.solver().particles().size(); ++i) {
    const double* x = &probe.solver().particles().x[3 * i];
    const double r2 = std::pow(x[0] - 0.2, 2) + std::pow(x[1] - 0.15, 2) + std::pow(x[2] - 0.3, 2);
    ball += r2 <= 0.08 * 0.08;
  }
  ASSERT_GT(ball, 100);
  expect_scene(kSandAndBall, 1600, 1000, ball);
}

TEST(MultiMaterialMpm, PasteOnAMetalPlateIsBitIdenticalAcrossRankCounts) {
  // The plate: particles with z < 0.076, i.e. 3 of the 12 lattice layers (z = 0.0125, 0.0375,
  // 0.0625) of 16 x 12 points.
  expect_scene(kPasteOnPlate, 1200, 7800, 16L * 12 * 3);
}

// The voxel solver: a cantilever of two halves under gravity, near its static sag (implicit
// Euler with steps far longer than its period damps the motion): the beam with a soft outer
// half sags more than a stiff beam and less than a soft one; bit-identical across rank counts.
const std::string kTwoHalves =
    test::TestDeck()
        .simulation(0.05, 2.0)
        .unpadded(0.05)
        .box({0, 0, 0}, {0.4, 0.1, 0.1})
        .table("[material]", {{"model", test::quoted("corotated")},
                              {"target", test::quoted("analytic")},
                              {"youngs_modulus", "2e7"},
                              {"poisson_ratio", "0.3"},
                              {"density", "1000"}})
        .region("material", {0.2, -1, -1}, {1, 1, 1},
                {{"model", test::quoted("corotated")},
                 {"target", test::quoted("analytic")},
                 {"youngs_modulus", "2e6"},
                 {"poisson_ratio", "0.3"},
                 {"density", "1000"}})
        .table("solver", {{"accuracy_tolerance", "1e-5"}, {"max_extra_outer", "3000"}})
        .clamp();

//! Lowest z of the free end after `steps` steps, and the total mass (rank 0).
std::pair<double, double> tip_and_mass(MPI_Comm comm, const Config& cfg, int steps) {
  elastogen::Simulation sim(comm, cfg);
  for (int s = 0; s < steps; ++s) EXPECT_TRUE(sim.dynamics().step(s * cfg.dt).accurate);
  const auto x = test::gather_positions(sim);
  double tip = 1e9;
  for (std::size_t i = 0; i + 2 < x.size(); i += 3)
    if (x[i] > 0.39) tip = std::min(tip, x[i + 2]);
  double local = 0, mass = 0;
  const auto& m = sim.system().mass();
  const auto& O = sim.system().owned();
  const auto& G = sim.system().ghosted();
  for (long k = O.start[2]; k < O.start[2] + O.count[2]; ++k)
    for (long j = O.start[1]; j < O.start[1] + O.count[1]; ++j)
      for (long i = O.start[0]; i < O.start[0] + O.count[0]; ++i) local += m[G.index(i, j, k)];
  MPI_Reduce(&local, &mass, 1, MPI_DOUBLE, MPI_SUM, 0, comm);
  return {tip, mass};
}

TEST(MultiMaterialElastoGen, StiffAndSoftHalvesSagBetweenTheUniformBeams) {
  const Config mixed = deck(kTwoHalves);
  const auto [tip, mass] = tip_and_mass(MPI_COMM_WORLD, mixed, 4);
  const auto stiff =
      tip_and_mass(MPI_COMM_WORLD, deck(kTwoHalves, {"material.1.youngs_modulus=2e7"}), 4);
  const auto soft =
      tip_and_mass(MPI_COMM_WORLD, deck(kTwoHalves, {"material.0.youngs_modulus=2e6"}), 4);
  // Each half's own density: 0.2 x 0.1 x 0.1 m^3 of each.
  const auto light = tip_and_mass(MPI_COMM_WORLD, deck(kTwoHalves, {"material.1.density=500"}), 0);
  if (test::world_rank() != 0) return;
  EXPECT_NEAR(mass, 0.004 * 1000, 1e-9);
  EXPECT_NEAR(light.second, 0.002 * (1000 + 500), 1e-9);
  EXPECT_LT(stiff.first, 0.0);  // it sags
  EXPECT_LT(soft.first, tip);
  EXPECT_LT(tip, stiff.first);
  // One rank gives the same bits.
  EXPECT_EQ(tip_and_mass(MPI_COMM_SELF, mixed, 4).first, tip);
}

}  // namespace
}  // namespace gen4d
