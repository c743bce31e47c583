// Decks a user can trust: tables and keys a solver does not read are refused by name, load
// curves, physically impossible inputs, the cylinder primitive, [[collider]] under the MPM.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "core/Deck.hpp"
#include "core/DeckUse.hpp"
#include "core/Error.hpp"
#include "deck_test_util.hpp"
#include "geometry/Shape.hpp"
#include "mpm/MpmSimulation.hpp"

namespace gen4d::test {
namespace {

//! [material] of both decks, written as the tests below edit it.
const Keys kJelly = {{"youngs_modulus", "1e5"}, {"poisson_ratio", "0.3"}, {"density", "1000"}};

const std::string kVoxel = TestDeck()
                               .simulation(0.01, 0.1)
                               .domain(0.1)
                               .box({0, 0, 0}, {1, 0.2, 0.2})
                               .table("material", kJelly);

const std::string kMpm = TestDeck()
                             .simulation(0.01, 0.1)
                             .mpm()
                             .domain(0.1)
                             .box({0, 0, 0}, {0.4, 0.4, 0.4})
                             .material(1e5, 0.3, 1000, {{"model", quoted("fixed_corotated")}})
                             .str();

Config parse(const std::string& text, const std::vector<std::string>& sets = {}) {
  return parse_deck(text, "deck.toml", ".", sets);
}

//! The InputError message of parsing `text`, or "" when it parses.
std::string error_of(const std::string& text, const std::vector<std::string>& sets = {}) {
  try {
    parse(text, sets);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

std::string use_error(const Config& c, DeckUser user) {
  try {
    check_deck_use(c, user);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

int line_of(const std::string& text, const std::string& needle) {
  const auto pos = text.find(needle);
  return pos == std::string::npos
             ? 0
             : 1 + static_cast<int>(std::count(text.begin(), text.begin() + pos, '\n'));
}

//! Expects parsing `text` to fail with "deck.toml:LINE: " + `message`, LINE that of the first
//! `needle` in `text`.
void expect_error_at(const std::string& text, const std::string& needle,
                     const std::string& message) {
  const std::string e = error_of(text);
  EXPECT_NE(e.find(fmt::format("deck.toml:{}: {}", line_of(text, needle), message)),
            std::string::npos)
      << e;
}

//! `deck` with its box replaced by the cylinder of axis [0, 0, 0] - `b`, radius 0.3.
std::string with_cylinder(std::string deck, const std::string& b = "[1, 0.5, 0.25]") {
  const auto from = deck.find("type = \"box\"");
  const auto to = deck.find('\n', deck.find("hi = ", from));
  return deck.replace(from, to - from,
                      "type = \"cylinder\"\na = [0, 0, 0]\nb = " + b + "\nradius = 0.3");
}

TEST(DeckUse, VoxelSectionsUnderTheMpmAreRefusedAtTheirLine) {
  for (const std::string table : {"fixed", "force", "kinematic", "traction"}) {
    std::string deck = kMpm + "[[" + table + "]]\nlo = [0, 0, 0]\nhi = [1, 1, 1]\n";
    if (table == "force") deck += "force = [0, 0, 1]\n";
    if (table == "traction") deck += "pressure = 10\n";
    expect_error_at(deck, "[[" + table,
                    fmt::format("[[{}]] does not apply to solver.method = \"mpm\"", table));
  }
  // The same, given with --set: the message points at the override.
  const std::string e = error_of(kMpm, {"fixed.0.lo=[0,0,0]", "fixed.0.hi=[1,1,1]"});
  EXPECT_EQ(e.rfind("--set fixed.0.", 0), 0u) << e;
}

TEST(DeckUse, KeysOfTheOtherSolverAreRefused) {
  const std::string surface = kMpm + "[output]\nsurface = \"ply\"\n";
  expect_error_at(surface,
                  "surface =", "key 'output.surface' does not apply to solver.method = \"mpm\"");
  std::string e = error_of(kMpm + "[solver.extra]\n");  // not a key: the schema's own error
  EXPECT_FALSE(e.empty());
  e = error_of(kVoxel + "[output]\nparticles = \"ply\"\n");
  EXPECT_NE(e.find("key 'output.particles' does not apply to solver.method = \"elastogen\""),
            std::string::npos)
      << e;
  e = error_of(kVoxel + "[mpm]\ncfl = 0.5\n");
  EXPECT_NE(e.find("deck.toml:14: [mpm] does not apply"), std::string::npos) << e;
  e = error_of(kVoxel + "[[boundary]]\ntype = \"bounding_box\"\n");
  EXPECT_NE(e.find("[[boundary]] does not apply"), std::string::npos) << e;
  // A render setting the voxel solvers do not read is accepted with a warning.
  EXPECT_EQ(error_of(kVoxel + "[render]\ncovariance_update = \"rate\"\n"), "");
  std::string mpm = kMpm;
  mpm.replace(mpm.find("method = \"mpm\""), 14, "method = \"mpm\"\nrelaxation = \"cg\"");
  e = error_of(mpm);
  EXPECT_NE(e.find("deck.toml:6: key 'solver.relaxation' does not apply"), std::string::npos) << e;
  // The Newton reference accepts (and warns about) ElastoGen's settings: one deck, two solvers.
  EXPECT_EQ(error_of(kVoxel + "[solver]\nmethod = \"newton\"\nrelaxation = \"cg\"\n"), "");
}

TEST(DeckUse, DiagnoseRefusesWhatItDoesNotModel) {
  const Config plain = parse(kVoxel);
  EXPECT_EQ(use_error(plain, DeckUser::Diagnose), "");
  // Output and render settings are how a run is written: accepted with a warning.
  EXPECT_EQ(use_error(parse(kVoxel + "[output]\ndir = \"x\"\n"), DeckUser::Diagnose), "");
  const std::string kin = kVoxel + "[[kinematic]]\nlo = [0, 0, 0]\nhi = [0.1, 1, 1]\n";
  std::string e = use_error(parse(kin), DeckUser::Diagnose);
  EXPECT_NE(e.find("deck.toml:14: [[kinematic]] does not apply to gen4d diagnose"),
            std::string::npos)
      << e;
  EXPECT_EQ(use_error(parse(kin), DeckUser::Elastogen), "");
  const std::string box = kVoxel + "[[collider]]\ntype = \"box\"\nlo = [2, 0, 0]\nhi = [3, 1, 1]\n";
  e = use_error(parse(box), DeckUser::Diagnose);
  EXPECT_NE(e.find("key 'collider.lo' does not apply to gen4d diagnose (gen4d diagnose takes "
                   "plane colliders)"),
            std::string::npos)
      << e;
  const std::string ramp = kVoxel +
                           "[[curve]]\nname = \"ramp\"\ntime = [0, 0.1]\nfactor = [0, 1]\n"
                           "[[force]]\nlo = [0.9, 0, 0]\nhi = [1, 1, 1]\nforce = [0, 0, 1]\n"
                           "curve = \"ramp\"\n";
  e = use_error(parse(ramp), DeckUser::Diagnose);
  EXPECT_NE(e.find("does not apply to gen4d diagnose"), std::string::npos) << e;
  // An MPM deck under diagnose: [[collider]] is refused (diagnose's MPM takes [[boundary]]).
  const Config mpm = parse(kMpm +
                           "[[collider]]\ntype = \"plane\"\npoint = [0, 0, 0]\n"
                           "normal = [0, 0, 1]\n");
  EXPECT_EQ(use_error(mpm, DeckUser::Mpm), "");
  e = use_error(mpm, DeckUser::Diagnose);
  EXPECT_NE(e.find("[[collider]] does not apply to gen4d diagnose"), std::string::npos) << e;
}

TEST(DeckUse, MpmCollidersBecomeGridConditions) {
  const Config c = parse(kMpm +
                         "[[collider]]\ntype = \"plane\"\npoint = [0, 0, -0.1]\n"
                         "normal = [0, 0, 2]\nfriction = 0.3\n"
                         "[[collider]]\ntype = \"box\"\nlo = [1, 1, 1]\nhi = [2, 2, 2]\n");
  const auto bcs = mpm::boundary_conditions(c);
  ASSERT_EQ(bcs.size(), 2u);
  EXPECT_EQ(bcs[0].type, "surface_collider");
  EXPECT_EQ(bcs[0].surface, "separate");
  EXPECT_EQ(bcs[0].normal, (Vec3d{0, 0, 1}));
  EXPECT_EQ(bcs[0].point, (Vec3d{0, 0, -0.1}));
  EXPECT_EQ(bcs[0].friction, 0.3);
  EXPECT_EQ(bcs[1].type, "cuboid");
  EXPECT_EQ(bcs[1].motion, "fixed");
  EXPECT_EQ(bcs[1].velocity, (Vec3d{0, 0, 0}));
  EXPECT_EQ(bcs[1].region.lo, (Vec3d{1, 1, 1}));
  // A box obstacle of the MPM holds what touches it: friction on it is refused.
  const std::string e = error_of(
      kMpm + "[[collider]]\ntype = \"box\"\nlo = [1, 1, 1]\nhi = [2, 2, 2]\nfriction = 0.2\n");
  EXPECT_NE(e.find("key 'collider.0.friction': an MPM box collider holds"), std::string::npos) << e;
}

TEST(DeckCurves, ValuesIntegralsAndRoundTrip) {
  const std::string deck = kVoxel +
                           "[[curve]]\nname = \"ramp\"\ntime = [0, 0.1, 0.2]\n"
                           "factor = [0, 1, 0.5]\n"
                           "[[force]]\nlo = [0.9, 0, 0]\nhi = [1, 1, 1]\nforce = [0, 0, 1]\n"
                           "curve = \"ramp\"\n";
  const Config c = parse(deck);
  ASSERT_EQ(c.curves.size(), 1u);
  const Curve& k = c.forces[0].curve;
  EXPECT_EQ(k.name(), "ramp");
  EXPECT_EQ(k(-1), 0.0);  // held before the first point
  EXPECT_EQ(k(0.05), 0.5);
  EXPECT_DOUBLE_EQ(k(0.15), 0.75);
  EXPECT_EQ(k(3), 0.5);  // and after the last
  EXPECT_DOUBLE_EQ(k.integral(0, 0.1), 0.05);
  EXPECT_DOUBLE_EQ(k.integral(0.05, 0.3), 0.0375 + 0.075 + 0.05);
  EXPECT_DOUBLE_EQ(k.integral(-1, 0), 0.0);
  EXPECT_EQ(Curve()(12.0), 1.0);
  EXPECT_EQ(Curve().integral(1, 3), 2.0);
  // A restart re-reads the stored text: the same curve.
  const Config again = parse_deck(c.text, "stored", ".");
  EXPECT_EQ(again.forces[0].curve.times(), k.times());
  EXPECT_EQ(again.forces[0].curve.factors(), k.factors());
  // --set reaches a curve's arrays.
  const Config set = parse(deck, {"curve.0.factor=[0, 2, 1]"});
  EXPECT_EQ(set.forces[0].curve(0.1), 2.0);
}

TEST(DeckCurves, BadCurvesAreRefusedByKey) {
  const std::string force =
      "[[force]]\nlo = [0.9, 0, 0]\nhi = [1, 1, 1]\nforce = [0, 0, 1]\ncurve = \"ramp\"\n";
  const auto with = [&](const std::string& curve) { return error_of(kVoxel + curve + force); };
  std::string e = with("[[curve]]\nname = \"ramp\"\ntime = [0, 0.1, 0.1]\nfactor = [0, 1, 1]\n");
  EXPECT_NE(e.find("deck.toml:16: key 'curve.0.time': must increase strictly"), std::string::npos)
      << e;
  e = with("[[curve]]\nname = \"ramp\"\ntime = [0, 0.1]\nfactor = [0]\n");
  EXPECT_NE(e.find("key 'curve.0.factor': needs one value per time (2), got 1"), std::string::npos)
      << e;
  e = with("[[curve]]\nname = \"ramp\"\ntime = []\nfactor = []\n");
  EXPECT_NE(e.find("key 'curve.0.time'"), std::string::npos) << e;
  e = with("[[curve]]\nname = \"rmap\"\ntime = [0]\nfactor = [1]\n");
  EXPECT_NE(e.find("key 'force.0.curve': no [[curve]] is named 'ramp' (did you mean 'rmap'?)"),
            std::string::npos)
      << e;
  e = error_of(kVoxel + force);
  EXPECT_NE(e.find("the deck has no [[curve]] table"), std::string::npos) << e;
  e = with(
      "[[curve]]\nname = \"ramp\"\ntime = [0]\nfactor = [1]\n"
      "[[curve]]\nname = \"ramp\"\ntime = [0]\nfactor = [2]\n");
  EXPECT_NE(e.find("key 'curve.1.name': another [[curve]] is named 'ramp'"), std::string::npos)
      << e;
  e = with(
      "[[curve]]\nname = \"ramp\"\ntime = [0]\nfactor = [1]\n"
      "[[curve]]\nname = \"spare\"\ntime = [0]\nfactor = [2]\n");
  EXPECT_NE(e.find("key 'curve.1.name': no load names curve 'spare'"), std::string::npos) << e;
  // Under the MPM a curve is for [[boundary]] conditions; one that none names is refused.
  e = error_of(kMpm + "[[curve]]\nname = \"ramp\"\ntime = [0]\nfactor = [1]\n");
  EXPECT_NE(e.find("no load names curve 'ramp'"), std::string::npos) << e;
  e = error_of(kMpm +
               "[[boundary]]\ntype = \"surface_collider\"\npoint = [0, 0, 0]\n"
               "normal = [0, 0, 1]\ncurve = \"ramp\"\n");
  EXPECT_NE(e.find("curve"), std::string::npos) << e;  // colliders take no curve
}

TEST(DeckPhysics, ImpossibleMaterialsAreRefusedByKey) {
  const auto replace = [](std::string text, const std::string& from, const std::string& to) {
    return text.replace(text.find(from), from.size(), to);
  };
  struct Case {
    std::string from, to, message;
  };
  for (const Case& c :
       {Case{"density = 1000", "density = 0", "key 'material.density': must be > 0"},
        Case{"youngs_modulus = 1e5", "youngs_modulus = -1",
             "key 'material.youngs_modulus': must be > 0"},
        Case{"poisson_ratio = 0.3", "poisson_ratio = 0.5",
             "key 'material.poisson_ratio': must be in (-1, 0.5)"},
        Case{"poisson_ratio = 0.3", "poisson_ratio = -1", "key 'material.poisson_ratio'"}})
    EXPECT_NE(error_of(replace(kVoxel, c.from, c.to)).find(c.message), std::string::npos) << c.to;
  const std::string hot =
      replace(kMpm, "\"fixed_corotated\"",
              "\"von_mises\"\njc_A = 3e8\nmelt_temperature = 1700\ninitial_temperature = 1800");
  expect_error_at(hot, "initial_temperature",
                  "key 'material.initial_temperature': must be below melt_temperature (1700 K");
  EXPECT_EQ(error_of(replace(hot, "initial_temperature = 1800", "initial_temperature = 1600")), "");
  // Yield stress and cohesion must be >= 0: the MPM registry refuses them, naming the key.
  const auto material_error = [&](const std::string& text) {
    try {
      mpm::make_deck_material(parse(text));
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  std::string e =
      material_error(replace(kMpm, "\"fixed_corotated\"", "\"von_mises\"\nyield_stress = -5"));
  EXPECT_NE(e.find("material.yield_stress"), std::string::npos) << e;
  e = material_error(
      replace(kMpm, "fixed_corotated\"", "drucker_prager\"\nfriction_angle = 30\ncohesion = -1"));
  EXPECT_NE(e.find("material.cohesion"), std::string::npos) << e;
}

TEST(DeckGeometry, CylinderVolumeOnVoxelsAndParticles) {
  const Config c = parse(with_cylinder(kVoxel));
  ASSERT_EQ(c.geometry[0].type, "cylinder");
  const auto shape = geometry::make_shape(c.geometry);
  const double r = 0.3, len = std::sqrt(1.0 + 0.25 + 0.0625);
  const double volume = M_PI * r * r * len, area = 2 * M_PI * r * (r + len);
  // Points of a lattice of spacing s decide "inside" correctly farther than s sqrt(3) / 2
  // from the surface: the counted volume is within area * s sqrt(3) / 2 of the true one.
  for (const double s : {0.05, 0.025}) {
    const geometry::Aabb b = shape->bounds();
    std::array<long, 3> lo{}, hi{};
    for (int d = 0; d < 3; ++d) {
      lo[d] = static_cast<long>(std::floor(b.lo[d] / s)) - 1;
      hi[d] = static_cast<long>(std::ceil(b.hi[d] / s)) + 1;
    }
    std::vector<std::uint8_t> occ;
    geometry::voxelize(*shape, Eigen::Vector3d::Zero(), s, lo, hi, occ);
    const double counted = static_cast<double>(geometry::count_solid(occ)) * s * s * s;
    EXPECT_NEAR(counted, volume, area * s * std::sqrt(3.0) / 2) << s;
    if (s == 0.025) EXPECT_NEAR(counted, volume, 0.03 * volume);
  }
  // Outside its bounds nothing is inside; the end discs are flat.
  EXPECT_TRUE(shape->inside(Eigen::Vector3d(0.5, 0.25, 0.125)));
  EXPECT_FALSE(shape->inside(Eigen::Vector3d(-0.05, 0, 0)));  // behind end a
  EXPECT_TRUE(shape->inside(Eigen::Vector3d(0.01, 0.0, 0.0)));
  // The MPM seeds it: particle count times particle volume.
  const Config m = parse(with_cylinder(kMpm), {"domain.voxel_size=0.05"});
  mpm::MpmSimulation sim(MPI_COMM_SELF, m);
  const double spacing = 0.05 / 2;
  const double seeded = static_cast<double>(sim.total_particles()) * std::pow(spacing, 3);
  EXPECT_NEAR(seeded, volume, area * spacing * std::sqrt(3.0) / 2);
  EXPECT_NEAR(seeded, volume, 0.03 * volume);
  // Its keys are the capsule's; a == b has no axis.
  const std::string e = error_of(with_cylinder(kVoxel, "[0, 0, 0]"));
  EXPECT_NE(e.find("key 'geometry.0.b': must differ from a"), std::string::npos) << e;
}

}  // namespace
}  // namespace gen4d::test
