// Tests of gen4d diagnose on MPM decks: the MPM solver as the forward model (markers follow the
// particles, the library's effects reduce to the deck at their null values, the friction plane
// stops a sliding block where Coulomb says, runs spread over ranks match local runs), the
// refusals (voxel-only effects, accelerometers), and a diagnosis end to end: a block sliding on
// a floor the deck believes frictionless.
#include <gtest/gtest.h>
#include <mpi.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <regex>
#include <sstream>

#include "core/Deck.hpp"
#include "core/Error.hpp"
#include "diagnose/Diagnose.hpp"
#include "diagnose/Effects.hpp"
#include "diagnose/Fit.hpp"
#include "diagnose/Forward.hpp"
#include "diagnose/Recording.hpp"
#include "test_diagnose_common.hpp"

using namespace gen4d;
using namespace gen4d::diagnose;
using namespace gen4d::diagnose::testing;

namespace {

//! A jelly block (8 x 4 x 4 cm, 4 x 2 x 2 cells of 2 cm, 8 particles per cell) of modulus E
//! launched at `velocity` along a floor at z = 0 that the deck believes frictionless; `lifted`:
//! 6 cm up and 10 cm tall.
std::string slide_text(const Vec3d& velocity = {1, 0, 0}, const Vec3d& gravity = {0, 0, -9.81},
                       bool lifted = false, double youngs_modulus = 1e5) {
  using test::quoted, test::toml;
  return test::TestDeck()
      .simulation(1e-3, 0.6, {{"name", quoted("slide")}, {"gravity", toml(gravity)}})
      .mpm()
      .domain(0.02)
      .table("mpm", {{"lo", toml(Vec3d{-0.08, -0.1, -0.08})},
                     {"hi", toml(Vec3d{0.9, 0.14, 0.14})},
                     {"particles_per_axis", "2"},
                     {"velocity", toml(velocity)}})
      .box({0, 0, lifted ? 0.06 : 0}, {0.08, 0.04, lifted ? 0.1 : 0.04})
      .material(youngs_modulus, 0.3, 1000, {{"model", quoted("fixed_corotated")}})
      .table("[boundary]", {{"type", quoted("surface_collider")},
                            {"point", toml(Vec3d{0, 0, 0})},
                            {"normal", toml(Vec3d{0, 0, 1})},
                            {"surface", quoted("separate")},
                            {"friction", "0"}});
}
const std::string kSlide = slide_text();

Config slide_deck(const std::string& text = kSlide) {
  return parse_deck(text, "<slide deck>", ".");
}

const std::vector<Vec3d> kMarkers = {{0.0, 0.0, 0.04},  {0.04, 0.02, 0.04}, {0.08, 0.04, 0.04},
                                     {0.02, 0.0, 0.02}, {0.06, 0.04, 0.02}, {0.08, 0.0, 0.0}};

}  // namespace

TEST(DiagnoseMpmModel, RestStaysAtRestAndAFreeBlockFallsAsGravitySays) {
  const MpmModel m(slide_deck(slide_text({0, 0, 0}, {0, 0, -9.81}, true)));
  const std::vector<Vec3d> X = {{0.04, 0.02, 0.1}, {0.0, 0.0, 0.06}};
  const auto req = marker_requests(m, X, 8, 0.01);
  Physics rest = m.nominal();
  rest.gravity = {0, 0, 0};
  const Trace still = m.run(rest, req);
  ASSERT_TRUE(still.ok) << still.failure;
  for (std::size_t c = 0; c < X.size(); ++c)
    for (std::size_t k = 0; k < req[c].t.size(); ++k)
      for (int a = 0; a < 3; ++a) EXPECT_NEAR(still.channel[c][3 * k + a], X[c][a], 1e-12);
  // Falling freely (the kernels of the lowest particles, 6.5 cm up, reach the floor's nodes
  // after 0.09 s; here 0.08 s): symplectic Euler's
  // z = z0 - g dt^2 n (n + 1) / 2, within g t dt of the continuum's g t^2 / 2.
  const Trace fall = m.run(m.nominal(), req);
  ASSERT_TRUE(fall.ok) << fall.failure;
  const double g = 9.81, dt = m.substep();
  for (std::size_t c = 0; c < X.size(); ++c) {
    const double t = req[c].t.back();
    const double z = fall.channel[c][3 * (req[c].t.size() - 1) + 2];
    EXPECT_NEAR(z, X[c][2] - 0.5 * g * t * t, g * t * dt + 1e-9);
    EXPECT_NEAR(fall.channel[c][3 * (req[c].t.size() - 1)], X[c][0], 1e-12);
  }
}

TEST(DiagnoseMpmModel, EveryEffectItModelsIsTheDeckAtItsNullValue) {
  const Config cfg = slide_deck();
  const MpmModel m(cfg);
  const auto req = marker_requests(m, kMarkers, 30, 0.01);
  const Physics base = m.nominal();
  const Trace ref = m.run(base, req);
  ASSERT_TRUE(ref.ok) << ref.failure;
  EffectContext ctx = effect_context(m, base, 20, ref.max_mises);
  ctx.max_speed = ref.max_speed;
  ctx.amplitude = 0.01;
  ctx.lowest_point = 0;
  ctx.total_mass = m.volume() * base.density;
  ctx.surface_area = m.exposed_area();
  ctx.has_region = true;
  ctx.region = m.bounds();
  int modelled = 0;
  for (const auto& e : effect_library()) {
    // The supports' effects and the added masses are terms of the voxel model.
    const bool voxel_only = e->name() == "clamp_compliance" || e->name() == "support_rotation" ||
                            e->name() == "support_friction" || e->name() == "added_mass" ||
                            e->name() == "sensor_mass";
    EXPECT_EQ(m.models(e->name(), ""), !voxel_only) << e->name();
    if (voxel_only) continue;
    for (const auto& var : e->variants(ctx)) {
      ASSERT_TRUE(m.models(e->name(), var)) << e->name() << ":" << var;
      if (e->name() == "material_law") continue;  // no null value: another law
      Physics ph = base;
      e->apply(var, e->null_values(ctx, var), ctx, ph);
      const Trace tr = m.run(ph, req);
      ASSERT_TRUE(tr.ok) << e->name() << ": " << tr.failure;
      EXPECT_EQ(tr.channel, ref.channel) << e->name() << " " << var;
      ++modelled;
    }
  }
  // damping (mass, stiffness, rayleigh), viscoelasticity, plasticity, heterogeneity, gravity,
  // contact_friction, air_drag, coulomb_damping
  EXPECT_EQ(modelled, 10);
  // The other laws run, and move the markers.
  Physics neo = base;
  neo.law = "neo_hookean";
  const Trace tn = m.run(neo, req);
  ASSERT_TRUE(tn.ok);
  EXPECT_NE(tn.channel, ref.channel);
}

TEST(DiagnoseMpmModel, AFrictionPlaneStopsASlidingBlockWhereCoulombSays) {
  const MpmModel m(slide_deck());
  const auto req = marker_requests(m, {{0.04, 0.02, 0.04}}, 60, 0.01);
  auto slid = [&](double height, double mu) {
    Physics ph = m.nominal();
    set_effect_terms(ph, "contact_friction", {height, mu});
    const Trace tr = m.run(ph, req);
    EXPECT_TRUE(tr.ok) << tr.failure;
    return tr.channel[0][3 * 60] - 0.04;
  };
  // v0^2 / (2 mu g) = 0.170 m at mu 0.3, 0.102 m at 0.5.
  for (const double mu : {0.3, 0.5}) {
    const double d = slid(0.0, mu), coulomb = 1.0 / (2 * mu * 9.81);
    EXPECT_NEAR(d / coulomb, 1.0, 0.05) << "mu " << mu << ": slid " << d << " m";
  }
  // The plane's height acts continuously: blended over one cell above it, the block slides
  // farther the lower it lies; a plane two cells below the floor, past the kernels of the
  // lowest particles (whose nodes carry mass down to a cell below the floor), leaves it
  // sliding as on the deck's frictionless floor, bit for bit.
  const double d0 = slid(0.0, 0.3), d1 = slid(-0.005, 0.3), d2 = slid(-0.01, 0.3);
  EXPECT_LT(d0, d1);
  EXPECT_LT(d1, d2);
  EXPECT_NEAR(slid(-1e-4, 0.3), d0, 0.02 * d0);
  const double free = slid(-0.5, 0.3);
  EXPECT_EQ(slid(-0.041, 0.3), free);
  EXPECT_NEAR(free, 0.6, 1e-3);
}

namespace {

//! The slide block lifted off the floor (its lowest particles 6 cm up), flying at `v` with
//! gravity `g`: a rigid body, whatever acts on it.
MpmModel flying_block(const Vec3d& v, const Vec3d& g) {
  return MpmModel(slide_deck(slide_text(v, g, true)));
}

}  // namespace

TEST(DiagnoseMpmModel, AirDragAndDryFrictionSlowAFlyingBlockAsTheirLawsSay) {
  // No gravity, 1 m/s along x: the block is rigid, and its particles' exposed areas sum to the
  // box's surface, 2 (8 x 4) + 2 (8 x 4) + 2 (4 x 4) cm^2 = 0.016 m^2, for 0.128 kg.
  const MpmModel m = flying_block({1, 0, 0}, {0, 0, 0});
  EXPECT_NEAR(m.exposed_area(), 0.016, 1e-12);
  const double A = 0.016, mass = 0.128, T = 0.5;
  const auto req = marker_requests(m, {{0.04, 0.02, 0.1}}, 50, 0.01);
  auto travelled = [&](const Physics& ph) {
    const Trace tr = m.run(ph, req);
    EXPECT_TRUE(tr.ok) << tr.failure;
    return tr.channel[0][3 * 50] - 0.04;
  };
  EXPECT_NEAR(travelled(m.nominal()), T, 1e-9);
  // Linear drag c: v = v0 exp(-k t), k = c A / m = 2 1/s; x = v0 (1 - exp(-k T)) / k.
  Physics lin = m.nominal();
  set_effect_terms(lin, "air_drag", {2.0 * mass / A, 0});
  const double x_lin = (1 - std::exp(-2.0 * T)) / 2.0;
  EXPECT_NEAR(travelled(lin) / x_lin, 1.0, 2e-3) << "linear drag";
  // Quadratic drag: v = v0 / (1 + k v0 t), k = c A / m = 3 1/m; x = log(1 + k v0 T) / k.
  Physics quad = m.nominal();
  set_effect_terms(quad, "air_drag", {0, 3.0 * mass / A});
  EXPECT_NEAR(travelled(quad) / (std::log(1 + 3.0 * T) / 3.0), 1.0, 2e-3) << "quadratic drag";
  // Dry friction a_c = 4 m/s^2: the block stops after v0^2 / (2 a_c) = 0.125 m, at 0.25 s.
  Physics dry = m.nominal();
  set_effect_terms(dry, "coulomb_damping", {4.0});
  EXPECT_NEAR(travelled(dry) / 0.125, 1.0, 1e-2) << "dry friction";
}

TEST(DiagnoseMpmModel, ARegionFactorAPronyTermAndStiffnessDampingActOnTheStress) {
  // The slide block under gravity on the floor: it sags and rings while it slides.
  const MpmModel m(slide_deck());
  const auto req = marker_requests(m, kMarkers, 30, 0.01);
  const Physics base = m.nominal();
  const Trace ref = m.run(base, req);
  ASSERT_TRUE(ref.ok);
  auto max_apart = [&](const Trace& a, const Trace& b) {
    double d = 0;
    for (std::size_t c = 0; c < a.channel.size(); ++c)
      for (std::size_t k = 0; k < a.channel[c].size(); ++k)
        d = std::max(d, std::abs(a.channel[c][k] - b.channel[c][k]));
    return d;
  };
  auto run = [&](const Physics& ph) {
    const Trace tr = m.run(ph, req);
    EXPECT_TRUE(tr.ok) << tr.failure;
    return tr;
  };
  // A region holding the whole body at factor 1.5 is the body at 1.5 E (the elastic laws'
  // stresses are linear in E at the same nu), to rounding; half the body moves the markers.
  Physics whole = base;
  set_region(whole, m.bounds(), 1.5);
  Physics stiffer = base;
  stiffer.youngs_modulus *= 1.5;
  const Trace t_stiff = run(stiffer);
  EXPECT_LT(max_apart(run(whole), t_stiff), 1e-9);
  EXPECT_GT(max_apart(t_stiff, ref), 2e-5) << max_apart(t_stiff, ref);
  Physics half = base;
  BoxRegion half_box = m.bounds();
  half_box.hi[0] = 0.04;
  set_region(half, half_box, 1.5);
  const Trace t_half = run(half);
  EXPECT_GT(max_apart(t_half, ref), 5e-6) << max_apart(t_half, ref);
  EXPECT_GT(max_apart(t_half, t_stiff), 5e-6) << max_apart(t_half, t_stiff);
  // A Prony term relaxing far faster than the substep is the body at (1 - g) E; one relaxing
  // far slower is the elastic body (the relaxing stress is carried in the particle's rotated
  // frame, so the sliding block's rigid motion leaves it alone).
  Physics fast = base;
  set_effect_terms(fast, "viscoelasticity", {0.4, 1e-9});
  Physics softer = base;
  softer.youngs_modulus *= 0.6;
  const Trace t_soft = run(softer);
  EXPECT_LT(max_apart(run(fast), t_soft), 1e-6);
  Physics slow = fast;
  set_effect_terms(slow, "viscoelasticity", {0.4, 1e9});
  EXPECT_LT(max_apart(run(slow), ref), 1e-6);
  // Stiffness damping acts on the rate of deformation only: it does not slow the flying
  // block's rigid translation, and it damps the sag's ringing of the sliding one.
  const MpmModel fly = flying_block({1, 0, 0}, {0, 0, 0});
  const auto freq = marker_requests(fly, {{0.04, 0.02, 0.1}}, 30, 0.01);
  Physics fb = fly.nominal();
  set_effect_terms(fb, "damping", {0, 1e-3});
  const Trace t_fly = fly.run(fb, freq), t_fly0 = fly.run(fly.nominal(), freq);
  ASSERT_TRUE(t_fly.ok && t_fly0.ok) << t_fly.failure << t_fly0.failure;
  EXPECT_LT(max_apart(t_fly, t_fly0), 1e-9);
  Physics damped = base;
  set_effect_terms(damped, "damping", {0, 1e-3});
  const Trace t_damped = run(damped);
  // The top centre marker's vertical ringing about its late mean, over the last 0.1 s.
  auto ringing = [&](const Trace& tr) {
    const auto& z = tr.channel[1];
    double mean = 0, var = 0;
    for (int k = 20; k <= 30; ++k) mean += z[3 * k + 2] / 11;
    for (int k = 20; k <= 30; ++k) var += std::pow(z[3 * k + 2] - mean, 2) / 11;
    return std::sqrt(var);
  };
  EXPECT_LT(ringing(t_damped), 0.5 * ringing(ref))
      << ringing(t_damped) << " against " << ringing(ref);
}

TEST(DiagnoseMpmModel, RanksShareRunsBitForBit) {
  const Config cfg = slide_deck();
  const MpmModel m(cfg);
  Observations obs;
  obs.requests = marker_requests(m, kMarkers, 20, 0.01);
  add_fitted(obs, 1e-4);
  std::vector<Physics> batch(3, m.nominal());
  set_effect_terms(batch[1], "contact_friction", {0, 0.4});
  set_effect_terms(batch[2], "damping", {3, 0});
  Evaluator ev(MPI_COMM_WORLD, m, obs);
  const auto got = ev.run(batch);
  for (std::size_t i = 0; i < batch.size(); ++i) {
    const Trace local = m.run(batch[i], obs.requests);
    ASSERT_TRUE(got[i].ok && local.ok);
    std::vector<double> flat;
    for (const auto& ch : local.channel) flat.insert(flat.end(), ch.begin(), ch.end());
    EXPECT_EQ(got[i].y, flat) << i;
  }
}

TEST(DiagnoseMpm, RefusesClampComplianceAccelerometersAndVoxelOnlyDeckSections) {
  int size = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  const std::string dir = "diagnose_mpm_refusals_np" + std::to_string(size);
  const Config cfg = slide_deck();
  const MpmModel m(cfg);
  Recording rec;
  for (int s = 0; s < 2; ++s) {
    Channel ch;
    ch.kind = s == 0 ? ChannelKind::Position : ChannelKind::Acceleration;
    ch.id = s == 0 ? "m0" : "a0";
    ch.X = {0.04, 0.02, 0.04};
    for (int k = 0; k <= 20; ++k) {
      ch.t.push_back(0.01 * k);
      ch.value.push_back({0.04 + 0.01 * k + 1e-4 * std::sin(k), 0.02, 0.04});
    }
    rec.channels.push_back(ch);
  }
  write_fresh_recording(rec, dir);  // the sensor goes to rec-acc.csv
  DiagnoseOptions opt;
  opt.recordings = {dir + "/rec.csv", dir + "/rec-acc.csv"};
  opt.out_dir = dir + "/out";
  opt.effects = {"contact_friction", "clamp_compliance"};
  const auto diagnose = [&] { run_diagnose(MPI_COMM_WORLD, cfg, opt); };
  const std::string clamp = refusal(diagnose, "clamp_compliance on an MPM deck");
  EXPECT_NE(clamp.find("--effects clamp_compliance: the mpm model"), std::string::npos) << clamp;
  EXPECT_NE(clamp.find("no [[fixed]] supports"), std::string::npos) << clamp;
  opt.effects = {"contact_friction"};
  const std::string sensor = refusal(diagnose, "an accelerometer on an MPM deck");
  EXPECT_NE(sensor.find("sensor 'a0': the mpm model samples marker positions"), std::string::npos)
      << sensor;
  EXPECT_FALSE(std::filesystem::exists(opt.out_dir + "/report.json"));
  // Voxel-solver sections in an MPM deck are refused by name.
  const std::string fixed = kSlide + "[[fixed]]\nlo = [-1, -1, -1]\nhi = [0, 1, 1]\n";
  const std::string section =
      refusal([&] { MpmModel bad(slide_deck(fixed)); }, "[[fixed]] in an MPM deck");
  EXPECT_NE(section.find("[[fixed]] does not apply"), std::string::npos) << section;
}

namespace {

//! Diagnoses the slide deck (E 6 % low) against a recording of the block from a finer MPM
//! discretisation (27 particles per cell, half the substep; so it carries an error of its
//! own), on a floor with Coulomb friction `mu`, noise 1e-4 m; returns report.json (rank 0).
std::string diagnose_slide(double mu, const std::string& name) {
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  const Config truth_cfg = slide_deck();
  const double dt = MpmModel(truth_cfg).substep();
  Config fine = truth_cfg;
  fine.mpm.particles_per_axis = 3;
  fine.mpm.substep = "fixed";
  fine.dt = 0.5 * dt;
  const MpmModel truth_model(fine);
  Physics truth = truth_model.nominal();
  if (mu > 0) set_effect_terms(truth, "contact_friction", {0, mu});
  const auto req = marker_requests(truth_model, kMarkers, 60, 0.01);
  const Trace tr = truth_model.run(truth, req);
  EXPECT_TRUE(tr.ok) << tr.failure;
  if (!tr.ok) return {};
  const std::string dir = "diagnose_mpm_" + name + "_np" + std::to_string(size);
  write_fresh_recording(noisy_markers(kMarkers, req, tr, 1e-4, 5), dir);
  const Config cfg = slide_deck(slide_text({1, 0, 0}, {0, 0, -9.81}, false, 9.4e4));
  DiagnoseOptions opt;
  opt.recordings = {dir + "/rec.csv"};
  opt.out_dir = dir + "/out";
  EXPECT_EQ(run_diagnose(MPI_COMM_WORLD, cfg, opt), 0);
  return rank == 0 ? file_text(opt.out_dir + "/report.json") : std::string();
}

}  // namespace

TEST(DiagnoseMpmEndToEnd, SaysNothingIsMissingWhenOnlyEIsOff) {
  const std::string js = diagnose_slide(0.0, "slide_null");
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  if (rank != 0) return;
  EXPECT_NE(js.find("\"verdict\": \"none\""), std::string::npos) << js.substr(0, 800);
  EXPECT_NE(js.find("\"effect\": null"), std::string::npos);
}

TEST(DiagnoseMpmEndToEnd, FindsFrictionOnAFloorTheDeckBelievedFrictionless) {
  const std::string js = diagnose_slide(0.3, "slide");
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  if (rank != 0) return;
  const std::string dir = "diagnose_mpm_slide_np" + std::to_string(size);
  EXPECT_NE(js.find("\"verdict\": \"missing_physics\""), std::string::npos) << js.substr(0, 800);
  EXPECT_NE(js.find("\"effect\": \"contact_friction\""), std::string::npos) << js.substr(0, 800);
  EXPECT_NE(js.find("\"forward_model\": \"mpm\""), std::string::npos);
  // The cells' own error (the h/2 rerun) is below the noise here: the parameters are measured,
  // not effective values of coarse cells.
  EXPECT_NE(js.find("\"parameters_effective\": false"), std::string::npos);
  EXPECT_NE(js.find("{\"effect\": \"clamp_compliance\", \"why\": \"an MPM deck has no [[fixed]] "
                    "supports (its [[boundary]] conditions are kinematic)\"}"),
            std::string::npos);
  std::smatch mt;
  ASSERT_TRUE(std::regex_search(js, mt, std::regex("\"friction\": \\{\"value\": ([-0-9.e+]+)")));
  EXPECT_NEAR(std::stod(mt[1].str()), 0.3, 0.03);
  // The recording was made at half the substep: the fit's own time-step error (chi-square 221
  // on the fitted values, 238 residual variances) is the intervals' threshold, not the
  // noise's 3.84, and the friction's interval holds the truth. (At 3.84 it was
  // [0.300020, 0.300063] about 0.300061, and missed it.)
  EXPECT_NE(js.find("\"threshold_from\": \"time_step_error\""), std::string::npos) << js;
  ASSERT_TRUE(std::regex_search(
      js, mt,
      std::regex(
          "\"friction\": \\{\"value\": [-0-9.e+]+, \"ci95\": \\[([-0-9.e+]+), ([-0-9.e+]+)\\]")));
  EXPECT_LE(std::stod(mt[1].str()), 0.3);
  EXPECT_GE(std::stod(mt[2].str()), 0.3);
  ASSERT_TRUE(std::regex_search(js, mt, std::regex("\"heldout_rms_before\": ([-0-9.e+]+)")));
  const double before = std::stod(mt[1].str());
  ASSERT_TRUE(std::regex_search(js, mt, std::regex("\"heldout_rms_after\": ([-0-9.e+]+)")));
  EXPECT_LT(std::stod(mt[1].str()), 0.05 * before);
  const std::string md = file_text(dir + "/out/report.md");
  EXPECT_NE(md.find("forward model: the MPM solver"), std::string::npos);
}
