// Tests of gen4d diagnose's stages one at a time (Pipeline.hpp), each run on the state the
// stages before it left, on a tiny cantilever (8x2x2 voxels, 150 steps) recorded by the model
// itself with E 15 % above the deck's and mass damping the deck leaves out.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>
#include <string>

#include "core/Deck.hpp"
#include "diagnose/Pipeline.hpp"
#include "test_diagnose_common.hpp"

using namespace gen4d;
using namespace gen4d::diagnose;
using namespace gen4d::diagnose::testing;

namespace {

const std::string kDeck = cantilever(named("stage-beam", -9.81), 0.004, 0.6, {0.08, 0.02, 0.02},
                                     3e5, 0.075, pulse({0, 0.01, -0.01}, 0.1));

constexpr double kTrueE = 3e5 * 1.15, kTrueAlpha = 4.0, kNoise = 2e-5;

Config deck() {
  return parse_deck(kDeck, "<stage deck>", ".");
}

//! The recording (4 markers, every 5 ms, Gaussian noise kNoise), written once to a folder of
//! this rank count; its path.
std::string recording_path() {
  int size = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  const std::string dir = "diagnose_stages_np" + std::to_string(size);
  const std::string path = dir + "/rec.csv";
  static bool written = false;
  if (written) return path;
  written = true;
  const VoxelModel m(deck());
  Physics truth = m.nominal();
  truth.youngs_modulus = kTrueE;
  set_effect_terms(truth, "damping", {kTrueAlpha, 0});
  const std::vector<Vec3d> markers = {
      {0.08, 0.01, 0.02}, {0.06, 0.0, 0.01}, {0.04, 0.02, 0.0}, {0.08, 0.0, 0.0}};
  const auto req = marker_requests(m, markers, 120, 0.005);
  const Trace tr = m.run(truth, req);
  EXPECT_TRUE(tr.ok) << tr.failure;
  write_fresh_recording(noisy_markers(markers, req, tr, kNoise, 3), dir);
  return path;
}

//! Options: the recording, damping and gravity as the library, the best one refitted, no
//! discretisation checks (their finer voxels cost most of a diagnosis).
DiagnoseOptions options() {
  DiagnoseOptions opt;
  opt.recordings = {recording_path()};
  opt.out_dir = "diagnose_stages_out";
  opt.effects = {"damping", "gravity"};
  opt.refit = 1;
  opt.max_iterations = 6;
  opt.refinement_check = false;
  return opt;
}

//! A diagnosis state run through the stages before `stage` (in pipeline order).
struct Staged {
  Config cfg = deck();
  DiagnoseOptions opt = options();
  State s{MPI_COMM_WORLD, cfg, opt};
  explicit Staged(int stages) {
    void (*const order[])(State&) = {observe, calibrate,        locate, screen,
                                     refit,   diagnose::select, check};
    for (int k = 0; k < stages; ++k) order[k](s);
  }
};

}  // namespace

TEST(DiagnoseStages, ObserveSplitsTheRecordingAndMeasuresItsNoise) {
  Staged st(1);
  const State& s = st.s;
  ASSERT_EQ(s.obs.size(), 4u * 121u * 3u);
  long train = 0, held = 0;
  for (std::size_t i = 0; i < s.obs.size(); ++i) {
    EXPECT_NE(s.obs.train[i], s.obs.heldout[i]);  // each value either fitted or held out
    train += s.obs.train[i], held += s.obs.heldout[i];
  }
  EXPECT_EQ(s.ntrain, train);
  EXPECT_GT(held, 0);
  // Noise estimated model-free from the recording, within a third of the truth.
  EXPECT_NEAR(s.D.noise_position, kNoise, kNoise / 3);
  // The library is what --effects names; the dt/2 rerun is the numerical check's phase.
  ASSERT_EQ(s.library.size(), 2u);
  EXPECT_EQ(s.library[0]->name(), "damping");
  ASSERT_EQ(s.D.phases.size(), 1u);
  EXPECT_EQ(s.D.phases[0].runs, 2);
  EXPECT_TRUE(std::isfinite(s.D.numerical_change));
}

TEST(DiagnoseStages, CalibrateMovesTheStiffnessAndFindsAMisfit) {
  Staged st(2);
  const State& s = st.s;
  // E moves from the deck's towards the recording's (nu takes up part of the missing damping's
  // misfit), the fit improves on the deck, and the damping the deck leaves out shows as a
  // misfit.
  EXPECT_GT(s.D.youngs_modulus, 1.03 * 3e5);
  EXPECT_LT(s.D.youngs_modulus, 1.05 * kTrueE);
  EXPECT_LT(s.D.rms_before, 0.5 * s.D.rms_nominal);
  EXPECT_TRUE(s.D.misfit);
  EXPECT_GT(s.D.chi2_red, 2.0);
  EXPECT_DOUBLE_EQ(s.chi2_0, s.base.chi2);
  EXPECT_DOUBLE_EQ(s.calibrated.youngs_modulus, std::exp(s.base.z[0]));
}

TEST(DiagnoseStages, LocateFindsTheFrequencyAndTheWorstMarkers) {
  Staged st(3);
  const State& s = st.s;
  ASSERT_EQ(s.D.bin_t.size(), static_cast<std::size_t>(State::kBins));
  ASSERT_EQ(s.D.markers.size(), 3u);
  // The worst marker is the tip's (the largest motion, the largest damping error).
  const auto worst = std::max_element(s.D.channel_rms_before.begin(), s.D.channel_rms_before.end());
  EXPECT_EQ(s.D.markers[0],
            s.D.channel_ids[static_cast<std::size_t>(worst - s.D.channel_rms_before.begin())]);
  // The dominant frequency is the calibrated body's first bending mode.
  const double w_rest = s.model->rest_frequency(s.calibrated, motion_direction(s.obs, s.t_free));
  EXPECT_NEAR(s.ctx.omega / w_rest, 1.0, 0.1);
  EXPECT_GT(s.ctx.amplitude, 10 * kNoise);
}

TEST(DiagnoseStages, ScreenRanksTheMissingDampingFirst) {
  Staged st(4);
  const State& s = st.s;
  ASSERT_FALSE(s.screened.empty());
  // Both damping variants (mass, stiffness) before gravity, each explaining a third or more.
  ASSERT_GE(s.screened.size(), 3u);
  EXPECT_EQ(s.screened[0].effect, "damping");
  EXPECT_EQ(s.screened[1].effect, "damping");
  EXPECT_GT(s.screened[1].screen_gain, 0.3 * s.chi2_0);
  for (std::size_t k = 1; k < s.screened.size(); ++k)
    EXPECT_GE(s.screened[k - 1].screen_gain, s.screened[k].screen_gain);
}

TEST(DiagnoseStages, RefitAndSelectKeepMassDamping) {
  Staged st(6);
  const State& s = st.s;
  ASSERT_NE(s.best, nullptr);
  EXPECT_EQ(s.D.verdict, "missing_physics");
  EXPECT_EQ(s.D.effect, "damping");
  EXPECT_TRUE(s.best->passes);
  ASSERT_FALSE(s.D.effect_parameters.empty());
  EXPECT_EQ(s.D.effect_parameters[0].name, "alpha");
  EXPECT_NEAR(s.D.effect_parameters[0].value / kTrueAlpha, 1.0, 0.05);
  // With the damping fitted, E is the recording's.
  EXPECT_NEAR(s.D.youngs_modulus / kTrueE, 1.0, 0.02);
  // Refitted: the chosen effect's variants only (--refit 1).
  for (const Candidate& c : s.variant_fits) EXPECT_EQ(c.effect, "damping");
}

TEST(DiagnoseStages, CheckDrawsIntervalsAroundTheFit) {
  Staged st(7);
  const State& s = st.s;
  ASSERT_TRUE(s.D.time_step.done);
  ASSERT_FALSE(s.D.effect_parameters.empty());
  const ParamEstimate& pe = s.D.effect_parameters[0];
  EXPECT_LT(pe.ci_lo, pe.value);
  EXPECT_GT(pe.ci_hi, pe.value);
  EXPECT_GT(s.D.intervals.threshold, 0.0);
}

TEST(DiagnoseStages, ReportWritesTheVerdict) {
  Staged st(7);
  report(st.s);
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  EXPECT_EQ(st.s.D.signatures.size(), 5u);
  EXPECT_EQ(st.s.D.phases.back().name, "signatures");
  if (rank == 0) EXPECT_TRUE(std::filesystem::exists(st.opt.out_dir + "/report.json"));
}
