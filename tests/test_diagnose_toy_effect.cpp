// An effect defined in one file outside the library (a uniform sideways body acceleration),
// added to it with add_effect, recorded by the forward model and diagnosed: the effect is
// selected and its parameter recovered; a recording without it (the deck's beam at another E)
// is not blamed on it.
#include <gtest/gtest.h>
#include <mpi.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <random>
#include <string>

#include "core/Deck.hpp"
#include "diagnose/Pipeline.hpp"
#include "test_diagnose_common.hpp"

using namespace gen4d;
using namespace gen4d::diagnose;
using namespace gen4d::diagnose::testing;

namespace {

//! A body acceleration a along +y on every free node (particle). Terms: {a}.
class SidePush final : public Effect {
 public:
  std::string name() const override { return "side_push"; }
  std::string summary() const override { return "a uniform body acceleration along +y"; }
  std::string signature() const override { return "a sideways static offset"; }
  std::vector<ParamSpec> params(const EffectContext&, const std::string&) const override {
    return {{"accel", "m/s^2", 0.0, 5.0, false}};
  }
  std::vector<std::vector<std::vector<double>>> probe_groups(const EffectContext&,
                                                             const std::string&) const override {
    return {{{0.2}}};
  }
  bool scalable() const override { return true; }
  std::vector<double> null_values(const EffectContext&, const std::string&) const override {
    return {0};
  }
  void apply(const std::string&, const std::vector<double>& p, const EffectContext&,
             Physics& ph) const override {
    set_effect_terms(ph, *this, {p[0]});
  }
  std::vector<double> absent_terms() const override { return {0}; }
  void add_terms(const std::vector<double>& v, ModelTerms& t) const override {
    t.node_forces.push_back(std::make_shared<Push>(v[0]));
  }

 private:
  class Push final : public NodeForce {
   public:
    explicit Push(double a) : a_(a) {}
    void add_residual(const ForceNode& n, const double*, const double*, double,
                      double r[3]) const override {
      r[1] -= n.mass * a_;
    }
    void apply_to_particle(const ForceNode&, double dt, double v[3], double& speed) const override {
      v[1] += dt * a_;
      speed = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    }

   private:
    double a_;
  };
};

const std::string kDeck = cantilever(named("toy-beam", -9.81), 0.004, 0.4, {0.08, 0.02, 0.02}, 3e5,
                                     0.075, pulse({0, 0.01, -0.01}, 0.1));

constexpr double kTruePush = 1.0, kTrueAlpha = 4.0, kNoise = 2e-5;

Config deck() {
  return parse_deck(kDeck, "<toy deck>", ".");
}

//! The library with the toy effect in it (added once).
void add_toy_effect() {
  static const bool added = [] {
    add_effect(std::make_unique<SidePush>());
    return true;
  }();
  (void)added;
}

//! A recording of the deck's beam with `truth` (4 markers, every 5 ms, noise kNoise) in folder
//! `name`; its path.
std::string record(const std::string& name, const Physics& truth) {
  const VoxelModel m(deck());
  const std::vector<Vec3d> markers = {
      {0.08, 0.01, 0.02}, {0.06, 0.0, 0.01}, {0.04, 0.02, 0.0}, {0.08, 0.0, 0.0}};
  const auto req = marker_requests(m, markers, 80, 0.005);
  const Trace tr = m.run(truth, req);
  EXPECT_TRUE(tr.ok) << tr.failure;
  const std::string dir = "diagnose_toy_" + name;
  write_fresh_recording(noisy_markers(markers, req, tr, kNoise, 7), dir);
  return dir + "/rec.csv";
}

//! The diagnosis of `recording` with damping and the toy effect as the library, both refitted,
//! through model selection.
struct Diagnosed {
  Config cfg = deck();
  DiagnoseOptions opt;
  std::unique_ptr<State> s;
  explicit Diagnosed(const std::string& recording) {
    opt.recordings = {recording};
    opt.out_dir = recording + ".out";
    opt.effects = {"damping", "side_push"};
    opt.refit = 2;
    opt.max_iterations = 6;
    opt.refinement_check = false;
    s = std::make_unique<State>(MPI_COMM_WORLD, cfg, opt);
    for (void (*stage)(State&) : {observe, calibrate, locate, screen, refit, diagnose::select})
      stage(*s);
  }
};

}  // namespace

TEST(DiagnoseToyEffect, IsSelectedAndItsParameterRecovered) {
  add_toy_effect();
  const VoxelModel m(deck());
  Physics truth = m.nominal();
  set_effect_terms(truth, "side_push", {kTruePush});
  const Diagnosed d(record("push", truth));
  const State& s = *d.s;
  EXPECT_EQ(s.D.verdict, "missing_physics");
  EXPECT_EQ(s.D.effect, "side_push");
  ASSERT_EQ(s.D.effect_parameters.size(), 1u);
  EXPECT_EQ(s.D.effect_parameters[0].name, "accel");
  EXPECT_NEAR(s.D.effect_parameters[0].value / kTruePush, 1.0, 0.05);
}

TEST(DiagnoseToyEffect, IsNotBlamedForARecordingWithoutIt) {
  add_toy_effect();
  const VoxelModel m(deck());
  Physics truth = m.nominal();
  truth.youngs_modulus *= 1.1;  // the calibration's to find, no effect's
  const Diagnosed d(record("null", truth));
  const State& s = *d.s;
  EXPECT_EQ(s.D.verdict, "none");
  EXPECT_NE(s.D.effect, "side_push");
}
