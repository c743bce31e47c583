// MPM snow (Stomakhin et al. 2013): the hardened fixed-corotated stress inside the elastic band,
// the clamp of the elastic stretches in compression and in stretch with the plastic volume ratio
// J_p taking the rest (det F conserved), hardening after compaction, deck validation, and a snow
// block dropped on a floor that compacts, identically at every rank count.
#include <gtest/gtest.h>
#include <mpi.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "core/Error.hpp"
#include "geometry/Shape.hpp"
#include "materials/Mat3.hpp"
#include "mpm/Material.hpp"
#include "mpm/Seeding.hpp"
#include "mpm/Solver.hpp"
#include "mpm_test_util.hpp"
#include "mat3_test_util.hpp"

namespace gen4d {
namespace {

using gen4d::test::from_eigen;
using gen4d::test::to_eigen;
using materials::Mat3;

// Stomakhin et al.'s reference snow: E = 1.4e5 Pa, nu = 0.2, density 400 kg/m^3, and the
// model's default theta_c = 2.5e-2, theta_s = 7.5e-3, xi = 10.
constexpr double kE = 1.4e5, kNu = 0.2, kRho = 400;
constexpr double kThetaC = 2.5e-2, kThetaS = 7.5e-3, kXi = 10;
const double kMu = kE / (2 * (1 + kNu));
const double kLambda = kE * kNu / ((1 + kNu) * (1 - 2 * kNu));

mpm::MaterialParams snow_params(std::map<std::string, double> extra = {}) {
  mpm::MaterialParams p;
  p.model = "snow";
  p.source = "snow.toml";
  p.values = {{"youngs_modulus", kE}, {"poisson_ratio", kNu}, {"density", kRho}};
  int line = 2;
  for (const auto& [k, v] : extra) p.values[k] = v;
  for (const auto& [k, v] : p.values) p.where[k] = "snow.toml:" + std::to_string(line++);
  return p;
}

std::shared_ptr<const mpm::Material> snow(std::map<std::string, double> extra = {}) {
  return mpm::make_material(snow_params(std::move(extra)));
}

struct State {
  double s[mpm::kStateSize];
};

State state_with_jp(const mpm::Material& m, double Jp) {
  State st;
  m.init_state(st.s);
  st.s[0] = Jp;
  return st;
}

Mat3 update(const mpm::Material& m, Mat3& F, State& st) {
  Mat3 tau;
  m.update(1, F.a, st.s, tau.a, 1e-4);
  return tau;
}

Mat3 stress(const mpm::Material& m, const Mat3& F, const State& st) {
  Mat3 tau;
  m.stress(1, F.a, st.s, tau.a);
  return tau;
}

Eigen::Matrix3d random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> n;
  return Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized().toRotationMatrix();
}

double max_abs(const Eigen::Matrix3d& A) {
  return A.cwiseAbs().maxCoeff();
}

//! Singular values of F, descending (Eigen, independent of the solver's SVD).
Eigen::Vector3d singular_values(const Mat3& F) {
  return Eigen::JacobiSVD<Eigen::Matrix3d>(to_eigen(F)).singularValues();
}

//! Stomakhin's stress by hand: tau = 2 mu h (F - R) F^T + lambda h (J - 1) J I with
//! h = exp(xi (1 - J_p)) and R the polar rotation of F (det F > 0).
Eigen::Matrix3d hand_tau(const Mat3& Fm, double Jp, double xi = kXi) {
  const Eigen::Matrix3d F = to_eigen(Fm);
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d R = svd.matrixU() * svd.matrixV().transpose();
  const double J = F.determinant();
  const double h = std::exp(xi * (1 - Jp));
  return 2 * kMu * h * (F - R) * F.transpose() +
         kLambda * h * (J - 1) * J * Eigen::Matrix3d::Identity();
}

// Q1 diag(s) Q2 for random rotations.
Mat3 rotated_diag(std::mt19937_64& rng, double a, double b, double c, Eigen::Matrix3d& Q1,
                  Eigen::Matrix3d& Q2) {
  Q1 = random_rotation(rng);
  Q2 = random_rotation(rng);
  return from_eigen(Q1 * Eigen::Vector3d(a, b, c).asDiagonal() * Q2);
}

// ---------------------------------------------------------------------------------------------
// The material

TEST(MpmSnow, RegisteredWithItsKeysAndDefaults) {
  const auto names = mpm::material_names();
  EXPECT_NE(std::find(names.begin(), names.end(), "snow"), names.end());
  EXPECT_EQ(mpm::material_keys("snow"),
            (std::vector<std::string>{"critical_compression", "critical_stretch",
                                      "hardening_coefficient"}));
  const auto m = snow();
  EXPECT_EQ(m->name(), "snow");
  EXPECT_EQ(m->state_names(), std::vector<std::string>{"plastic_jacobian"});
  State st;
  m->init_state(st.s);
  EXPECT_EQ(st.s[0], 1.0);
  // The substep limit uses the largest hardening, exp(xi), of the P-wave modulus.
  EXPECT_NEAR(m->wave_speed(), std::sqrt(std::exp(kXi) * (kLambda + 2 * kMu) / kRho),
              1e-12 * m->wave_speed());
  EXPECT_NEAR(snow({{"hardening_coefficient", 0}})->wave_speed(),
              std::sqrt((kLambda + 2 * kMu) / kRho), 1e-12 * m->wave_speed());
  // The adaptive substep's bound: the hardening of the most compacted particle at hand, compacted
  // by one more full clamp; at rest about 100 times below the state-free bound.
  auto bound = [&](double jp) {
    const double h = std::exp(kXi * (1 - jp * std::pow(1 - kThetaC, 3)));
    return std::sqrt(h * (kLambda + 2 * kMu) / kRho);
  };
  State three[3];
  for (State& p : three) m->init_state(p.s);
  std::vector<double> states;
  for (const State& p : three) states.insert(states.end(), p.s, p.s + mpm::kStateSize);
  EXPECT_NEAR(m->state_wave_speed(3, states.data()), bound(1.0), 1e-12 * bound(1.0));
  EXPECT_GT(m->wave_speed() / m->state_wave_speed(3, states.data()), 90);
  states[mpm::kStateSize] = 0.7;  // the second particle compacted
  states[2 * mpm::kStateSize] = 1.3;
  EXPECT_NEAR(m->state_wave_speed(3, states.data()), bound(0.7), 1e-12 * bound(0.7));
  states[0] = 0.0;  // fully compacted: the state-free bound
  EXPECT_NEAR(m->state_wave_speed(3, states.data()), m->wave_speed(), 1e-12 * m->wave_speed());
  // Models without state-dependent stiffness keep their one bound.
  const auto jelly = [] {
    mpm::MaterialParams p;
    p.model = "fixed_corotated";
    p.values = {{"youngs_modulus", kE}, {"poisson_ratio", kNu}, {"density", kRho}};
    return mpm::make_material(p);
  }();
  EXPECT_EQ(jelly->state_wave_speed(3, states.data()), jelly->wave_speed());
}

TEST(MpmSnow, BadKeysAreLocatedInputErrors) {
  auto message = [](std::map<std::string, double> extra) -> std::string {
    try {
      snow(std::move(extra));
    } catch (const InputError& e) {
      return e.what();
    }
    return "no error";
  };
  EXPECT_NE(message({{"critical_compression", 1.0}})
                .find("material.critical_compression must be "
                      "in [0, 1), got 1"),
            std::string::npos)
      << message({{"critical_compression", 1.0}});
  EXPECT_NE(message({{"critical_compression", 1.0}}).find("snow.toml:"), std::string::npos);
  EXPECT_NE(message({{"critical_stretch", -0.1}}).find("material.critical_stretch must be >= 0"),
            std::string::npos);
  EXPECT_NE(message({{"hardening_coefficient", -1}}).find("material.hardening_coefficient"),
            std::string::npos);
  EXPECT_NE(message({{"hardening_coefficient", 800}}).find("material.hardening_coefficient"),
            std::string::npos);
  // von_mises' hardening modulus is not the snow's hardening coefficient.
  EXPECT_NE(message({{"hardening", 10}}).find("material.hardening is not a key of model snow"),
            std::string::npos);
  EXPECT_EQ(message({{"critical_compression", 0}, {"critical_stretch", 0}}), "no error");
}

TEST(MpmSnow, RestStateIsStressFreeAndUnchanged) {
  const auto m = snow();
  Mat3 F = materials::identity3();
  State st = state_with_jp(*m, 1.0);
  const Mat3 tau = update(*m, F, st);
  for (int k = 0; k < 9; ++k) {
    EXPECT_EQ(F.a[k], materials::identity3().a[k]);
    EXPECT_LE(std::fabs(tau.a[k]), 1e-12 * kE);
  }
  EXPECT_EQ(st.s[0], 1.0);
}

// (1) Inside [1 - theta_c, 1 + theta_s] the update leaves F and J_p exactly as they are and the
// stress is fixed corotated with mu, lambda scaled by exp(xi (1 - J_p)).
TEST(MpmSnow, ElasticBandIsHardenedFixedCorotated) {
  const auto m = snow();
  // Diagonal F by hand: J = 0.98 * 1.005 * 0.99, J_p = 0.9: h = e^1.
  {
    const double s0 = 0.98, s1 = 1.005, s2 = 0.99, Jp = 0.9;
    const double J = s0 * s1 * s2, h = std::exp(1.0);
    Mat3 F{{s0, 0, 0, 0, s1, 0, 0, 0, s2}};
    State st = state_with_jp(*m, Jp);
    const Mat3 tau = update(*m, F, st);
    const double s[3] = {s0, s1, s2};
    for (int i = 0; i < 3; ++i) {
      const double expected = 2 * kMu * h * (s[i] - 1) * s[i] + kLambda * h * (J - 1) * J;
      EXPECT_NEAR(tau(i, i), expected, 1e-12 * kE) << i;
      for (int j = 0; j < 3; ++j)
        if (j != i) EXPECT_LE(std::fabs(tau(i, j)), 1e-12 * kE);
    }
    EXPECT_EQ(st.s[0], Jp);
    // The hardening is really applied: the stress differs from the unhardened one by h = e.
    const double unhardened = 2 * kMu * (s0 - 1) * s0 + kLambda * (J - 1) * J;
    EXPECT_NEAR(tau(0, 0) / unhardened, h, 1e-10);
  }
  // Rotated F, several J_p, against Eigen's polar decomposition.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> band(1 - kThetaC + 1e-4, 1 + kThetaS - 1e-4);
  for (double Jp : {1.0, 0.9, 0.75, 1.1}) {
    for (int trial = 0; trial < 20; ++trial) {
      Eigen::Matrix3d Q1, Q2;
      Mat3 F = rotated_diag(rng, band(rng), band(rng), band(rng), Q1, Q2);
      const Mat3 F0 = F;
      State st = state_with_jp(*m, Jp);
      const Mat3 tau = update(*m, F, st);
      for (int k = 0; k < 9; ++k) EXPECT_EQ(F.a[k], F0.a[k]);
      EXPECT_EQ(st.s[0], Jp);
      const Eigen::Matrix3d ref = hand_tau(F0, Jp);
      EXPECT_LE(max_abs(to_eigen(tau) - ref), 1e-9 * (max_abs(ref) + 1)) << Jp;
      EXPECT_LE(max_abs(to_eigen(stress(*m, F0, st)) - ref), 1e-9 * (max_abs(ref) + 1)) << Jp;
    }
  }
}

//! Checks one plastic update of Q1 diag(a, b, c) Q2 from J_p = Jp0: the elastic F becomes
//! Q1 diag(clamped) Q2, J_p absorbs the rest (J_e J_p = det F J_p0), and tau is the hardened
//! stress of the clamped F at the new J_p. Returns the new J_p.
double expect_clamped(double a, double b, double c, double Jp0, std::mt19937_64& rng) {
  const auto m = snow();
  Eigen::Matrix3d Q1, Q2;
  Mat3 F = rotated_diag(rng, a, b, c, Q1, Q2);
  const double J_trial = to_eigen(F).determinant();
  State st = state_with_jp(*m, Jp0);
  const Mat3 tau = update(*m, F, st);
  auto clamp = [](double x) { return std::clamp(x, 1 - kThetaC, 1 + kThetaS); };
  const Eigen::Matrix3d expected_F =
      Q1 * Eigen::Vector3d(clamp(a), clamp(b), clamp(c)).asDiagonal() * Q2;
  EXPECT_LE(max_abs(to_eigen(F) - expected_F), 1e-14);
  std::vector<double> want = {clamp(a), clamp(b), clamp(c)};
  std::sort(want.rbegin(), want.rend());
  const Eigen::Vector3d sv = singular_values(F);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(sv[k], want[k], 2e-15) << k;
  const double Jp = st.s[0];
  const double J_e = to_eigen(F).determinant();
  EXPECT_NEAR(J_e * Jp, J_trial * Jp0, 1e-14 * J_trial * Jp0);
  EXPECT_NEAR(Jp, Jp0 * a * b * c / (clamp(a) * clamp(b) * clamp(c)), 1e-14 * Jp);
  const Eigen::Matrix3d ref = hand_tau(F, Jp);
  EXPECT_LE(max_abs(to_eigen(tau) - ref), 1e-9 * max_abs(ref));
  // The projected F is admissible: a second update changes it and J_p at most by rounding (the
  // recomposed F's singular values may land an ulp outside the band).
  const Mat3 F1 = F;
  update(*m, F, st);
  for (int k = 0; k < 9; ++k) EXPECT_NEAR(F.a[k], F1.a[k], 1e-15);
  EXPECT_NEAR(st.s[0], Jp, 1e-15 * Jp);
  return Jp;
}

// (2) Compression beyond theta_c: clamped to exactly 1 - theta_c, J_p decreases.
TEST(MpmSnow, CompressionBeyondCriticalIsPlastic) {
  std::mt19937_64 rng(8);
  const double Jp = expect_clamped(0.9, 0.95, 1.0, 1.0, rng);
  EXPECT_LT(Jp, 1.0);
  EXPECT_NEAR(Jp, 0.9 * 0.95 / ((1 - kThetaC) * (1 - kThetaC)), 1e-14);
  // Uniform compression, starting from an already compacted particle.
  const double Jp2 = expect_clamped(0.9, 0.9, 0.9, 0.8, rng);
  EXPECT_NEAR(Jp2, 0.8 * std::pow(0.9 / (1 - kThetaC), 3), 1e-14);
  EXPECT_LT(Jp2, 0.8);
}

// (3) Stretch beyond theta_s: clamped to exactly 1 + theta_s, J_p grows; both at once.
TEST(MpmSnow, StretchBeyondCriticalIsPlastic) {
  std::mt19937_64 rng(9);
  const double Jp = expect_clamped(1.05, 1.002, 0.99, 1.0, rng);
  EXPECT_GT(Jp, 1.0);
  EXPECT_NEAR(Jp, 1.05 / (1 + kThetaS), 1e-14);
  const double Jmix = expect_clamped(1.1, 1.0, 0.8, 0.95, rng);
  EXPECT_NEAR(Jmix, 0.95 * 1.1 * 0.8 / ((1 + kThetaS) * (1 - kThetaC)), 1e-14);
}

// (4) After a plastic compaction the same elastic strain carries exp(xi (1 - J_p)) times the
// stress; a stretched (J_p > 1) particle is softer; xi = 0 disables hardening.
TEST(MpmSnow, CompactionHardens) {
  const auto m = snow();
  Mat3 F{{0.8, 0, 0, 0, 0.85, 0, 0, 0, 0.9}};
  State st = state_with_jp(*m, 1.0);
  update(*m, F, st);
  const double Jp = st.s[0];
  EXPECT_NEAR(Jp, 0.8 * 0.85 * 0.9 / std::pow(1 - kThetaC, 3), 1e-14);
  const Mat3 Fe{{0.99, 0, 0, 0, 1.0, 0, 0, 0, 1.005}};  // in the band
  const Mat3 tau_virgin = stress(*m, Fe, state_with_jp(*m, 1.0));
  const Mat3 tau_compacted = stress(*m, Fe, st);
  const double factor = std::exp(kXi * (1 - Jp));
  EXPECT_GT(factor, 5.0);  // J_p = 0.7766: e^2.23
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(tau_compacted(i, i), factor * tau_virgin(i, i), 1e-12 * factor * kE) << i;
  EXPECT_GT(std::fabs(tau_compacted(0, 0)), 5 * std::fabs(tau_virgin(0, 0)));
  // Softening after a plastic stretch.
  Mat3 G{{1.1, 0, 0, 0, 1.0, 0, 0, 0, 1.0}};
  State sg = state_with_jp(*m, 1.0);
  update(*m, G, sg);
  EXPECT_GT(sg.s[0], 1.0);
  EXPECT_LT(std::fabs(stress(*m, Fe, sg)(0, 0)), std::fabs(tau_virgin(0, 0)));
  // xi = 0: plastic, but no hardening.
  const auto soft = snow({{"hardening_coefficient", 0}});
  Mat3 H{{0.8, 0, 0, 0, 0.85, 0, 0, 0, 0.9}};
  State sh = state_with_jp(*soft, 1.0);
  update(*soft, H, sh);
  EXPECT_NEAR(sh.s[0], Jp, 1e-15);
  const Mat3 tau_soft = stress(*soft, Fe, sh);
  for (int k = 0; k < 9; ++k) EXPECT_NEAR(tau_soft.a[k], tau_virgin.a[k], 1e-12 * kE);
}

// An inverted trial F (signed SVD: sigma_2 < 0) is projected to the band with a finite,
// positive J_p.
TEST(MpmSnow, InvertedTrialStaysFinite) {
  const auto m = snow();
  Mat3 F{{1.0, 0, 0, 0, 1.0, 0, 0, 0, -0.5}};
  State st = state_with_jp(*m, 1.0);
  const Mat3 tau = update(*m, F, st);
  EXPECT_GT(st.s[0], 0.0);
  EXPECT_LT(st.s[0], 1e-5);
  EXPECT_GT(to_eigen(F).determinant(), 0.0);
  for (int k = 0; k < 9; ++k) EXPECT_TRUE(std::isfinite(tau.a[k]));
  const Eigen::Vector3d sv = singular_values(F);
  EXPECT_NEAR(sv[2], 1 - kThetaC, 1e-15);
}

// ---------------------------------------------------------------------------------------------
// (5) A snow block dropped on a floor

std::unique_ptr<mpm::Solver> drop(MPI_Comm comm) {
  mpm::SolverOptions opt;
  opt.max_dt = 2e-3;
  const std::vector<BoundaryConfig> floor = {mpm::surface_collider("sticky", {0, 0, 0}, {0, 0, 1})};
  return test::block_solver(comm, snow(), opt, floor, {0, 0, -2}, 0.3);
}

using test::gather_sorted;
using test::run;

TEST(MpmSnow, DroppedBlockCompactsIdenticallyAtEveryRankCount) {
  constexpr int kSubsteps = 1500;
  double t = 0;
  auto dist = drop(MPI_COMM_WORLD);
  run(*dist, kSubsteps, t);
  const auto a = gather_sorted(MPI_COMM_WORLD, dist->particles());
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  if (rank != 0) return;
  double ts = 0;
  auto serial = drop(MPI_COMM_SELF);
  run(*serial, kSubsteps, ts);
  const auto b = gather_sorted(MPI_COMM_SELF, serial->particles());
  ASSERT_EQ(a.size(), b.size());
  ASSERT_GT(a.size(), 0u);
  EXPECT_EQ(t, ts);
  long differ = 0;
  for (std::size_t i = 0; i < a.size(); ++i) differ += a[i] != b[i];
  EXPECT_EQ(differ, 0);

  // Record: id, x (3), v (3), C (9), F (9), state (kStateSize), mass, vol0, flag.
  const int R = mpm::Particles::kRecord;
  const int kF = 1 + 3 + 3 + 9, kState = kF + 9;
  const std::size_t n = a.size() / R;
  double jp_min = 1e300, jp_max = -1e300, sv_min = 1e300, sv_max = -1e300, z_max = -1e300;
  std::size_t compacted = 0;
  for (std::size_t i = 0; i < n; ++i) z_max = std::max(z_max, a[i * R + 3]);
  // Mean J_p of the bottom and of the top cell layer of the block.
  double bottom = 0, top = 0;
  int n_bottom = 0, n_top = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double* rec = &a[i * R];
    const double jp = rec[kState];
    ASSERT_TRUE(std::isfinite(jp));
    jp_min = std::min(jp_min, jp);
    jp_max = std::max(jp_max, jp);
    compacted += jp < 0.99;
    if (rec[3] < 0.05) bottom += jp, ++n_bottom;
    if (rec[3] > z_max - 0.05) top += jp, ++n_top;
    Mat3 F;
    std::copy_n(rec + kF, 9, F.a);
    const Eigen::Vector3d sv = singular_values(F);
    sv_min = std::min(sv_min, sv[2]);
    sv_max = std::max(sv_max, sv[0]);
  }
  ASSERT_GT(n_bottom, 0);
  ASSERT_GT(n_top, 0);
  bottom /= n_bottom;
  top /= n_top;
  std::printf(
      "[ snow     ] %zu particles, t = %.4g s after %d substeps (dt %.3g s): J_p in "
      "[%.6f, %.6f], %zu below 0.99, mean %.6f in the bottom layer, %.6f in the top "
      "layer; elastic stretches in [%.6f, %.6f]\n",
      n, t, kSubsteps, t / kSubsteps, jp_min, jp_max, compacted, bottom, top, sv_min, sv_max);
  // The impact compacts the snow, most where it hit the floor.
  EXPECT_LT(jp_min, 0.95);
  EXPECT_GT(compacted, 0u);
  EXPECT_LT(bottom, 0.95);
  EXPECT_LT(bottom, top);
  // Every elastic F ended inside the band up to the last substep's G2P, which moved F after the
  // clamp by dt C F (dt |C| well below 1e-3 here).
  EXPECT_GT(sv_min, 1 - kThetaC - 1e-3);
  EXPECT_LT(sv_max, 1 + kThetaS + 1e-3);
}

}  // namespace
}  // namespace gen4d
