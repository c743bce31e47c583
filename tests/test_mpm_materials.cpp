// MPM constitutive models (PhysGaussian App. B) and their registry: rest state, rotation
// covariance, stress = energy gradient for the hyperelastic models, and for every return map the
// elastic / on-surface / projection / monotonicity properties plus model-specific closed forms
// (Drucker-Prager apex and cone, von Mises uniaxial curve and Johnson-Cook, Herschel-Bulkley
// simple shear, fracture damage and separation).
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "core/Error.hpp"
#include "materials/Mat3.hpp"
#include "mpm/Material.hpp"
#include "mat3_test_util.hpp"

namespace mpm = gen4d::mpm;
using gen4d::materials::Mat3;
using gen4d::test::from_eigen;
using gen4d::test::to_eigen;

namespace {

constexpr double kSqrt23 = 0.816496580927726032732428024902;  // sqrt(2/3)
constexpr double kSqrt2 = 1.41421356237309504880168872420969808;
constexpr double kPi = 3.14159265358979323846;

// ---------------------------------------------------------------------------------------------
// Decks and calls

using Keys = std::vector<std::pair<std::string, double>>;

// A deck for `model` with E = 1e6 Pa, nu = 0.3, density 1000 unless `keys` overrides them; every
// key gets a line "test.toml:N" so messages can be checked for their location.
mpm::MaterialParams deck(const std::string& model, const Keys& keys, bool common = true) {
  mpm::MaterialParams p;
  p.model = model;
  p.source = "test.toml";
  p.where["model"] = "test.toml:1";
  int line = 2;
  auto put = [&](const std::string& k, double v) {
    p.values[k] = v;
    p.where[k] = "test.toml:" + std::to_string(line++);
  };
  if (common) {
    put("youngs_modulus", 1e6);
    put("poisson_ratio", 0.3);
    put("density", 1000);
  }
  for (const auto& [k, v] : keys) put(k, v);
  return p;
}

std::unique_ptr<mpm::Material> make(const std::string& model, const Keys& keys = {}) {
  return mpm::make_material(deck(model, keys));
}

double mu_of(const mpm::Material& m) {
  return m.youngs_modulus() / (2 * (1 + m.poisson_ratio()));
}
double lambda_of(const mpm::Material& m) {
  const double E = m.youngs_modulus(), nu = m.poisson_ratio();
  return E * nu / ((1 + nu) * (1 - 2 * nu));
}

struct State {
  double s[mpm::kStateSize];
};

State initial_state(const mpm::Material& m) {
  State st;
  m.init_state(st.s);
  return st;
}

Mat3 stress_of(const mpm::Material& m, const Mat3& F, const State& st) {
  Mat3 tau;
  m.stress(1, F.a, st.s, tau.a);
  return tau;
}

// One return-map update in place; returns tau.
Mat3 update(const mpm::Material& m, Mat3& F, State& st, double dt) {
  Mat3 tau;
  m.update(1, F.a, st.s, tau.a, dt);
  return tau;
}

// ---------------------------------------------------------------------------------------------
// Linear algebra reference (Eigen, independent of the solver's svd3)

Mat3 identity() {
  return gen4d::materials::identity3();
}

Mat3 diag(double a, double b, double c) {
  return Mat3{{a, 0, 0, 0, b, 0, 0, 0, c}};
}

double max_abs_diff(const Mat3& A, const Mat3& B) {
  double d = 0;
  for (int k = 0; k < 9; ++k) d = std::max(d, std::fabs(A.a[k] - B.a[k]));
  return d;
}

double norm(const Mat3& A) {
  return gen4d::materials::frobenius_norm(A);
}

double trace(const Mat3& A) {
  return A(0, 0) + A(1, 1) + A(2, 2);
}

Mat3 dev(const Mat3& A) {
  Mat3 D = A;
  const double m = trace(A) / 3;
  for (int k = 0; k < 3; ++k) D(k, k) -= m;
  return D;
}

Mat3 random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> normal;
  const Eigen::Matrix3d R = Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng))
                                .normalized()
                                .toRotationMatrix();
  return from_eigen(R);
}

// R1 diag(exp(e)) R2 with principal log strains e uniform in [lo, hi] (det > 0).
Mat3 random_F(std::mt19937_64& rng, double lo, double hi) {
  std::uniform_real_distribution<double> u(lo, hi);
  return random_rotation(rng) * diag(std::exp(u(rng)), std::exp(u(rng)), std::exp(u(rng))) *
         random_rotation(rng);
}

// Hencky strain of the left stretch, e = log(V) = log(F F^T) / 2, and its StVK-Hencky Kirchhoff
// stress tau = 2 mu e + lambda tr(e) I, from Eigen's symmetric eigensolver.
Mat3 hencky_strain_ref(const Mat3& F) {
  const Eigen::Matrix3d b = to_eigen(F) * to_eigen(F).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(b);
  const Eigen::Vector3d e = 0.5 * es.eigenvalues().array().log();
  return from_eigen(es.eigenvectors() * e.asDiagonal() * es.eigenvectors().transpose());
}

Mat3 hencky_tau_ref(const Mat3& F, double mu, double lambda) {
  Mat3 tau = (2 * mu) * hencky_strain_ref(F);
  const double tr = trace(hencky_strain_ref(F));
  for (int k = 0; k < 3; ++k) tau(k, k) += lambda * tr;
  return tau;
}

// ---------------------------------------------------------------------------------------------
// Energies of the hyperelastic models (written independently of the library)

double energy_fixed_corotated(const Mat3& F, double mu, double lambda) {
  const Eigen::Matrix3d M = to_eigen(F);
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d R = svd.matrixU() * svd.matrixV().transpose();  // det F > 0 here
  const double J = M.determinant();
  return mu * (M - R).squaredNorm() + 0.5 * lambda * (J - 1) * (J - 1);
}

double energy_stvk_hencky(const Mat3& F, double mu, double lambda) {
  const Mat3 e = hencky_strain_ref(F);
  const double tr = trace(e);
  return mu * gen4d::materials::frobenius_dot(e, e) + 0.5 * lambda * tr * tr;
}

double energy_neo_hookean(const Mat3& F, double mu, double lambda) {
  const Eigen::Matrix3d M = to_eigen(F);
  const double logJ = std::log(M.determinant());
  return 0.5 * mu * ((M.transpose() * M).trace() - 3) - mu * logJ + 0.5 * lambda * logJ * logJ;
}

// tau = (d psi / dF) F^T by central differences.
template <class Energy>
Mat3 tau_by_energy(const Mat3& F, Energy psi) {
  const double h = 1e-6;
  Mat3 P;
  for (int k = 0; k < 9; ++k) {
    Mat3 plus = F, minus = F;
    plus.a[k] += h;
    minus.a[k] -= h;
    P.a[k] = (psi(plus) - psi(minus)) / (2 * h);
  }
  return P * gen4d::materials::transpose(F);
}

struct JcParams {
  double A, B, n, C, m, rate0, T_room, T_melt;
  double flow(double eps_p, double rate, double T) const {
    const double Ts = std::clamp((T - T_room) / (T_melt - T_room), 0.0, 1.0);
    return (A + B * std::pow(eps_p, n)) * (1 + C * std::log(std::max(rate / rate0, 1.0))) *
           (1 - std::pow(Ts, m));
  }
};

// A representative deck per model, for the tests that apply to all of them.
const std::vector<std::pair<std::string, Keys>>& all_models() {
  static const std::vector<std::pair<std::string, Keys>> models = {
      {"fixed_corotated", {}},
      {"stvk_hencky", {}},
      {"neo_hookean", {}},
      {"drucker_prager", {{"friction_angle", 30}, {"cohesion", 1e3}}},
      {"von_mises", {{"yield_stress", 5e3}, {"hardening", 1e4}}},
      {"von_mises",
       {{"jc_A", 5e3},
        {"jc_B", 2e4},
        {"jc_n", 0.4},
        {"jc_C", 0.05},
        {"jc_m", 1.2},
        {"melt_temperature", 1500},
        {"specific_heat", 450}}},
      {"herschel_bulkley", {{"yield_stress", 2e3}, {"consistency", 50}, {"flow_index", 0.6}}},
      {"fracture", {{"fracture_strain", 0.02}, {"failure_strain", 0.05}}},
  };
  return models;
}

// =============================================================================================
// All models

TEST(MpmMaterials, RegistryListsEveryModel) {
  const auto names = mpm::material_names();
  for (const char* name : {"drucker_prager", "fixed_corotated", "fracture", "herschel_bulkley",
                           "neo_hookean", "stvk_hencky", "von_mises"})
    EXPECT_NE(std::find(names.begin(), names.end(), name), names.end()) << name;
  EXPECT_EQ(mpm::material_keys("drucker_prager"),
            (std::vector<std::string>{"friction_angle", "cohesion"}));
  EXPECT_TRUE(mpm::material_keys("neo_hookean").empty());
}

TEST(MpmMaterials, RestStateIsStressFreeAndUnchanged) {
  for (const auto& [model, keys] : all_models()) {
    const auto m = make(model, keys);
    EXPECT_EQ(m->name(), model);
    State st = initial_state(*m);
    const Mat3 tau0 = stress_of(*m, identity(), st);
    EXPECT_LE(norm(tau0), 1e-12 * m->youngs_modulus()) << model;
    Mat3 F = identity();
    const State before = st;
    const Mat3 tau = update(*m, F, st, 1e-4);
    EXPECT_LE(norm(tau), 1e-12 * m->youngs_modulus()) << model;
    EXPECT_LE(max_abs_diff(F, identity()), 1e-15) << model;
    for (int k = 0; k < mpm::kStateSize; ++k) EXPECT_EQ(st.s[k], before.s[k]) << model;
  }
}

TEST(MpmMaterials, WaveSpeedAndStateNames) {
  for (const auto& [model, keys] : all_models()) {
    const auto m = make(model, keys);
    EXPECT_NEAR(m->wave_speed(), std::sqrt((lambda_of(*m) + 2 * mu_of(*m)) / 1000.0),
                1e-12 * m->wave_speed());
    EXPECT_LE(m->state_names().size(), static_cast<std::size_t>(mpm::kStateSize));
  }
  const auto vm = make("von_mises", {{"yield_stress", 1}, {"initial_temperature", 400}});
  EXPECT_EQ(initial_state(*vm).s[1], 400);
  EXPECT_EQ(initial_state(*make("von_mises", {{"yield_stress", 1}})).s[1], 294);
}

TEST(MpmMaterials, StressIsRotationCovariant) {
  std::mt19937_64 rng(11);
  for (const auto& [model, keys] : all_models()) {
    const auto m = make(model, keys);
    for (int trial = 0; trial < 50; ++trial) {
      const Mat3 F = random_F(rng, -0.2, 0.2);
      const Mat3 Q = random_rotation(rng);
      State st = initial_state(*m);
      const Mat3 tau = stress_of(*m, F, st);
      const Mat3 rotated = stress_of(*m, Q * F, st);
      const Mat3 expected = Q * tau * gen4d::materials::transpose(Q);
      EXPECT_LE(max_abs_diff(rotated, expected), 1e-10 * (norm(tau) + 1)) << model;
      EXPECT_LE(max_abs_diff(tau, gen4d::materials::transpose(tau)), 1e-12 * (norm(tau) + 1))
          << model << ": tau not symmetric";
    }
  }
}

// The return maps are isotropic too: update(Q F) = Q update(F), same state, same rotated tau.
TEST(MpmMaterials, UpdateIsRotationCovariant) {
  std::mt19937_64 rng(12);
  for (const auto& [model, keys] : all_models()) {
    const auto m = make(model, keys);
    for (int trial = 0; trial < 50; ++trial) {
      Mat3 F = random_F(rng, -0.1, 0.1);
      const Mat3 Q = random_rotation(rng);
      Mat3 QF = Q * F;
      State a = initial_state(*m), b = a;
      const Mat3 tau = update(*m, F, a, 1e-3);
      const Mat3 tau_q = update(*m, QF, b, 1e-3);
      EXPECT_LE(max_abs_diff(QF, Q * F), 1e-12) << model;
      EXPECT_LE(max_abs_diff(tau_q, Q * tau * gen4d::materials::transpose(Q)),
                1e-10 * (norm(tau) + 1))
          << model;
      for (int k = 0; k < mpm::kStateSize; ++k)
        EXPECT_NEAR(a.s[k], b.s[k], 1e-9 * (std::fabs(a.s[k]) + 1e-6)) << model << " slot " << k;
      // The returned tau is the stress of the returned F and state.
      EXPECT_LE(max_abs_diff(tau, stress_of(*m, F, a)), 1e-10 * (norm(tau) + 1)) << model;
    }
  }
}

// Inverted, collapsed and hugely stretched F, tiny and huge dt: every model stays finite.
TEST(MpmMaterials, ExtremeDeformationsStayFinite) {
  std::mt19937_64 rng(13);
  std::vector<Mat3> Fs = {diag(1, 1, -0.5), diag(1, 1, 1e-9), diag(0, 0, 0),
                          diag(10, 0.1, 1), diag(50, 50, 50), diag(1e-3, 1e-3, 1e-3),
                          diag(-1, -1, 1)};
  for (int k = 0; k < 20; ++k) Fs.push_back(random_F(rng, -2, 2));
  for (int k = 0; k < 10; ++k) Fs.push_back(random_F(rng, -1, 1) * diag(1, 1, -1));
  auto models = all_models();
  models.push_back(
      {"herschel_bulkley", {{"yield_stress", 10}, {"consistency", 1e3}, {"flow_index", 0.1}}});
  models.push_back(
      {"herschel_bulkley", {{"yield_stress", 0}, {"consistency", 1e-3}, {"flow_index", 3}}});
  models.push_back({"von_mises", {{"jc_A", 1e3}, {"jc_B", 1e5}, {"jc_n", 0.05}, {"jc_C", 1.0}}});
  models.push_back({"drucker_prager", {{"friction_angle", 0}}});
  models.push_back({"drucker_prager", {{"friction_angle", 89.9}, {"cohesion", 1e4}}});
  for (const auto& [model, keys] : models) {
    const auto m = make(model, keys);
    for (const Mat3& F0 : Fs) {
      for (const double dt : {1e-12, 1e-4, 10.0}) {
        Mat3 F = F0;
        State st = initial_state(*m);
        for (int rep = 0; rep < 2; ++rep) {
          const Mat3 tau = update(*m, F, st, dt);
          for (int k = 0; k < 9; ++k) {
            ASSERT_TRUE(std::isfinite(tau.a[k])) << model;
            ASSERT_TRUE(std::isfinite(F.a[k])) << model;
          }
          for (int k = 0; k < mpm::kStateSize; ++k) ASSERT_TRUE(std::isfinite(st.s[k])) << model;
        }
      }
    }
  }
}

// Extreme flow exponents: the scalar returns still land on their surfaces.
TEST(MpmMaterials, ScalarReturnsConvergeForExtremeExponents) {
  std::mt19937_64 rng(14);
  for (const double n : {0.05, 0.2, 2.5, 4.0}) {
    const auto hb =
        make("herschel_bulkley", {{"yield_stress", 500}, {"consistency", 300}, {"flow_index", n}});
    const auto vm = make("von_mises", {{"jc_A", 1e3}, {"jc_B", 5e4}, {"jc_n", n}, {"jc_C", 0.5}});
    for (int trial = 0; trial < 50; ++trial) {
      for (const double dt : {1e-7, 1e-3, 1.0}) {
        const Mat3 F0 = random_F(rng, -0.05, 0.05);
        Mat3 F = F0;
        State st{};
        Mat3 tau = update(*hb, F, st, dt);
        if (st.s[0] > 0) {
          const double flow = 500 + 300 * std::pow(st.s[0] / dt, n);
          EXPECT_NEAR(norm(dev(tau)) / kSqrt2, flow, 1e-9 * flow) << n << " " << dt;
        }
        F = F0;
        st = initial_state(*vm);
        tau = update(*vm, F, st, dt);
        if (st.s[0] > 0) {
          const JcParams jc{1e3, 5e4, n, 0.5, 1, 1, 294, std::numeric_limits<double>::infinity()};
          const double flow = jc.flow(st.s[0], st.s[2], 294);
          EXPECT_NEAR(norm(dev(tau)) / kSqrt23, flow, 1e-9 * flow) << n << " " << dt;
        }
      }
    }
  }
}

// =============================================================================================
// Hyperelastic models: tau = (d psi / dF) F^T

TEST(MpmMaterials, HyperelasticStressIsEnergyGradient) {
  std::mt19937_64 rng(21);
  struct Case {
    const char* model;
    double (*psi)(const Mat3&, double, double);
  };
  for (const Case& c :
       {Case{"fixed_corotated", energy_fixed_corotated}, Case{"stvk_hencky", energy_stvk_hencky},
        Case{"neo_hookean", energy_neo_hookean}}) {
    const auto m = make(c.model);
    const double mu = mu_of(*m), lambda = lambda_of(*m);
    for (int trial = 0; trial < 40; ++trial) {
      const Mat3 F = random_F(rng, -0.3, 0.3);
      const Mat3 tau = stress_of(*m, F, initial_state(*m));
      const Mat3 fd = tau_by_energy(F, [&](const Mat3& G) { return c.psi(G, mu, lambda); });
      EXPECT_LE(max_abs_diff(tau, fd), 1e-6 * norm(tau)) << c.model;
    }
  }
}

TEST(MpmMaterials, HyperelasticClosedForms) {
  std::mt19937_64 rng(22);
  const auto fcr = make("fixed_corotated");
  const auto hencky = make("stvk_hencky");
  const auto nh = make("neo_hookean");
  const double mu = mu_of(*fcr), lambda = lambda_of(*fcr);
  for (int trial = 0; trial < 20; ++trial) {
    const Mat3 F = random_F(rng, -0.3, 0.3);
    const Mat3 Ft = gen4d::materials::transpose(F);
    const Eigen::Matrix3d M = to_eigen(F);
    const double J = M.determinant();
    // Fixed corotated: 2 mu (F - R) F^T + lambda (J - 1) J I with R the polar rotation.
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
    const Mat3 R = from_eigen(svd.matrixU() * svd.matrixV().transpose());
    Mat3 expected = (2 * mu) * ((F - R) * Ft);
    for (int k = 0; k < 3; ++k) expected(k, k) += lambda * (J - 1) * J;
    EXPECT_LE(max_abs_diff(stress_of(*fcr, F, {}), expected), 1e-11 * norm(expected));
    // StVK-Hencky.
    const Mat3 th = hencky_tau_ref(F, mu, lambda);
    EXPECT_LE(max_abs_diff(stress_of(*hencky, F, {}), th), 1e-10 * norm(th));
    // Neo-Hookean.
    Mat3 tn = mu * (F * Ft - identity());
    for (int k = 0; k < 3; ++k) tn(k, k) += lambda * std::log(J);
    EXPECT_LE(max_abs_diff(stress_of(*nh, F, {}), tn), 1e-11 * norm(tn));
  }
  // Inverted or collapsed F gives a finite stress (clamped stretches), never NaN.
  for (const auto& m : {fcr.get(), hencky.get(), nh.get()}) {
    for (const Mat3& F : {diag(1, 1, -0.5), diag(1, 1, 0), diag(0, 0, 0)}) {
      const Mat3 tau = stress_of(*m, F, {});
      for (double x : tau.a) EXPECT_TRUE(std::isfinite(x)) << m->name();
    }
  }
}

// =============================================================================================
// Drucker-Prager

struct DpSetup {
  double alpha, k, mu, lambda;
  // f = |dev tau| + alpha tr(tau) - k, and a scale for relative checks.
  double f(const Mat3& tau) const { return norm(dev(tau)) + alpha * trace(tau) - k; }
  double scale(const Mat3& tau) const {
    return norm(dev(tau)) + alpha * std::fabs(trace(tau)) + k + 1e-300;
  }
};

DpSetup dp_setup(const mpm::Material& m, double phi_deg, double cohesion) {
  const double s = std::sin(phi_deg * kPi / 180), c = std::cos(phi_deg * kPi / 180);
  return {kSqrt23 * 2 * s / (3 - s), kSqrt23 * 6 * cohesion * c / (3 - s), mu_of(m), lambda_of(m)};
}

TEST(MpmDruckerPrager, ReturnMapProperties) {
  std::mt19937_64 rng(31);
  for (const double cohesion : {0.0, 2e3}) {
    const auto m = make("drucker_prager", {{"friction_angle", 35}, {"cohesion", cohesion}});
    const DpSetup dp = dp_setup(*m, 35, cohesion);
    int inside = 0, outside = 0, apex = 0;
    for (int trial = 0; trial < 400; ++trial) {
      Mat3 F = random_F(rng, -0.03, 0.02);
      const Mat3 trial_tau = hencky_tau_ref(F, dp.mu, dp.lambda);
      const Mat3 F0 = F;
      State st{{0, 0.25, 0, 0}};
      const Mat3 tau = update(*m, F, st, 1e-3);
      // The returned stress is the StVK-Hencky stress of the returned F and inside the cone.
      const Mat3 ref = hencky_tau_ref(F, dp.mu, dp.lambda);
      // Relative to the trial stress (the apex of c = 0 is tau = 0, known to rounding only).
      const double scale = std::max(dp.scale(ref), norm(trial_tau));
      EXPECT_LE(max_abs_diff(tau, ref), 1e-9 * scale);
      EXPECT_LE(dp.f(ref), 1e-9 * scale);
      EXPECT_GE(st.s[1], 0.25);  // plastic shear never decreases
      EXPECT_GE(st.s[0], 0.0);
      if (dp.f(trial_tau) < -1e-9 * dp.scale(trial_tau)) {
        ++inside;  // (a) elastic: F and state untouched
        EXPECT_EQ(max_abs_diff(F, F0), 0.0);
        EXPECT_EQ(st.s[0], 0.0);
        EXPECT_EQ(st.s[1], 0.25);
      } else if (dp.f(trial_tau) > 1e-9 * dp.scale(trial_tau)) {
        // (b) projected onto the surface (cone or apex).
        EXPECT_NEAR(dp.f(ref), 0.0, 1e-9 * scale);
        EXPECT_GT(st.s[1], 0.25);
        if (norm(dev(ref)) <= 1e-9 * scale)
          ++apex;
        else
          ++outside;
        // (c) a point on the surface maps to itself.
        Mat3 G = F;
        State again = st;
        update(*m, G, again, 1e-3);
        EXPECT_LE(max_abs_diff(G, F), 1e-12);
        EXPECT_NEAR(again.s[1], st.s[1], 1e-12);
      }
    }
    EXPECT_GT(inside, 20);
    EXPECT_GT(outside, 20);
    EXPECT_GT(apex, 20);
  }
}

// Points built exactly on the cone (and at the apex) map to themselves.
TEST(MpmDruckerPrager, SurfacePointsAreFixed) {
  std::mt19937_64 rng(32);
  std::uniform_real_distribution<double> u(-1, 1);
  const auto m = make("drucker_prager", {{"friction_angle", 25}, {"cohesion", 500}});
  const DpSetup dp = dp_setup(*m, 25, 500);
  const double K3 = 3 * dp.lambda + 2 * dp.mu;
  for (int trial = 0; trial < 100; ++trial) {
    const double tr = -0.03 * (u(rng) + 1) / 2;
    Eigen::Vector3d d(u(rng), u(rng), u(rng));
    d -= Eigen::Vector3d::Constant(d.sum() / 3);
    d.normalize();
    const double n = -(dp.alpha * K3 * tr - dp.k) / (2 * dp.mu);  // f = 0
    const Eigen::Vector3d e = Eigen::Vector3d::Constant(tr / 3) + n * d;
    Mat3 F = random_rotation(rng) * diag(std::exp(e[0]), std::exp(e[1]), std::exp(e[2])) *
             random_rotation(rng);
    const Mat3 F0 = F;
    State st{};
    update(*m, F, st, 1e-3);
    EXPECT_LE(max_abs_diff(F, F0), 1e-12);
    EXPECT_LE(st.s[1], 1e-12);
    EXPECT_EQ(st.s[0], 0.0);
  }
}

// With c = 0 sand has no tensile strength: hydrostatic or uniaxial tension goes to the apex,
// tau = 0, F becomes the polar rotation, and the volume gained is stored as log J_P.
TEST(MpmDruckerPrager, TensionGoesToTheApexWithoutCohesion) {
  std::mt19937_64 rng(33);
  const auto m = make("drucker_prager", {{"friction_angle", 30}});
  for (int trial = 0; trial < 50; ++trial) {
    const Mat3 Q1 = random_rotation(rng), Q2 = random_rotation(rng);
    std::uniform_real_distribution<double> u(0.001, 0.1);
    const double a = u(rng), b = u(rng) * 0.5, c = -u(rng) * 0.2;  // tr(e) > 0 if a+b+c > 0
    if (a + b + c <= 0) continue;
    Mat3 F = Q1 * diag(std::exp(a), std::exp(b), std::exp(c)) * Q2;
    State st{};
    const Mat3 tau = update(*m, F, st, 1e-3);
    EXPECT_LE(norm(tau), 1e-9 * m->youngs_modulus());
    EXPECT_LE(max_abs_diff(F, Q1 * Q2), 1e-12);
    EXPECT_NEAR(st.s[0], a + b + c, 1e-12);
    EXPECT_GT(st.s[1], 0.0);
  }
  // No random state ever carries a positive mean stress.
  const DpSetup dp = dp_setup(*m, 30, 0);
  for (int trial = 0; trial < 200; ++trial) {
    Mat3 F = random_F(rng, -0.05, 0.05);
    State st{};
    const Mat3 tau = update(*m, F, st, 1e-3);
    EXPECT_LE(trace(tau), 1e-9 * dp.scale(tau));
    EXPECT_LE(norm(dev(tau)), -dp.alpha * trace(tau) + 1e-9 * dp.scale(tau));  // the cone
  }
}

// Cohesion moves the apex to the hydrostatic tension tr(tau)/3 = c cot(phi).
TEST(MpmDruckerPrager, CohesionGivesTensileStrength) {
  const double phi = 30, c = 1e3;
  const auto m = make("drucker_prager", {{"friction_angle", phi}, {"cohesion", c}});
  const DpSetup dp = dp_setup(*m, phi, c);
  const double p_apex = c / std::tan(phi * kPi / 180);
  const double K = dp.lambda + 2 * dp.mu / 3;  // bulk modulus
  // Below the apex: elastic hydrostatic tension.
  const double e_small = 0.5 * p_apex / (3 * K);
  Mat3 F = diag(std::exp(e_small), std::exp(e_small), std::exp(e_small));
  State st{};
  Mat3 tau = update(*m, F, st, 1e-3);
  EXPECT_NEAR(trace(tau) / 3, 0.5 * p_apex, 1e-9 * p_apex);
  EXPECT_EQ(st.s[0], 0.0);
  // Past it: exactly the apex.
  const double e_big = 3 * p_apex / (3 * K);
  F = diag(std::exp(e_big), std::exp(e_big * 0.5), std::exp(e_big));
  st = State{};
  tau = update(*m, F, st, 1e-3);
  EXPECT_NEAR(trace(tau) / 3, p_apex, 1e-9 * p_apex);
  EXPECT_LE(norm(dev(tau)), 1e-9 * p_apex);
  EXPECT_NEAR(st.s[0], 2.5 * e_big - 3 * p_apex / (3 * K), 1e-12);
  // phi = 0 with cohesion: a cylinder |dev tau| <= k, any hydrostatic tension is elastic.
  const auto cyl = make("drucker_prager", {{"friction_angle", 0}, {"cohesion", c}});
  F = diag(1.01, 1.01, 1.01);
  st = State{};
  tau = update(*cyl, F, st, 1e-3);
  EXPECT_GT(trace(tau), 0.0);
  EXPECT_EQ(st.s[1], 0.0);
  F = diag(1.05, 0.98, 0.99);
  tau = update(*cyl, F, st, 1e-3);
  EXPECT_NEAR(norm(dev(tau)), kSqrt23 * 6 * c / 3, 1e-9 * c);
}

// Klar's volume correction: after separating (apex, log J_P = v > 0), re-compression by less than
// v stays stress-free; compression beyond it is elastic from the rest volume.
TEST(MpmDruckerPrager, VolumeCorrection) {
  const auto m = make("drucker_prager", {{"friction_angle", 30}});
  const DpSetup dp = dp_setup(*m, 30, 0);
  Mat3 F = diag(1.03, 1.03, 1.03);
  State st{};
  update(*m, F, st, 1e-3);
  const double v = 3 * std::log(1.03);
  EXPECT_NEAR(st.s[0], v, 1e-13);
  EXPECT_LE(max_abs_diff(F, identity()), 1e-13);
  // Compress by half the gained volume: still at the apex, half the correction left.
  const double h = std::exp(-v / 6);
  F = diag(h, h, h) * F;
  Mat3 tau = update(*m, F, st, 1e-3);
  EXPECT_LE(norm(tau), 1e-6);
  EXPECT_NEAR(st.s[0], v / 2, 1e-13);
  // Compress by the rest plus 1 %: elastic compression by 1 % of volume, correction used up.
  const double g = std::exp(-v / 6 - 0.01 / 3);
  F = diag(g, g, g) * F;
  tau = update(*m, F, st, 1e-3);
  EXPECT_EQ(st.s[0], 0.0);
  const double K3 = 3 * dp.lambda + 2 * dp.mu;
  EXPECT_NEAR(trace(tau), -K3 * 0.01, 1e-9 * K3 * 0.01);
  EXPECT_NEAR(std::log(gen4d::materials::det(F)), -0.01, 1e-12);
}

TEST(MpmDruckerPrager, PlasticShearNeverDecreases) {
  std::mt19937_64 rng(34);
  std::uniform_real_distribution<double> u(-0.01, 0.01);
  const auto m = make("drucker_prager", {{"friction_angle", 30}, {"cohesion", 200}});
  Mat3 F = identity();
  State st{};
  double last = 0;
  for (int step = 0; step < 500; ++step) {
    Mat3 dF = identity();
    for (double& x : dF.a) x += u(rng);
    F = dF * F;
    update(*m, F, st, 1e-3);
    EXPECT_GE(st.s[1], last);
    EXPECT_GE(st.s[0], 0.0);
    last = st.s[1];
  }
  EXPECT_GT(last, 0.0);
}

// =============================================================================================
// von Mises

const JcParams kJc{5e3, 2e4, 0.4, 0.05, 1.2, 1.0, 294, 1500};
const Keys kJcKeys{{"jc_A", 5e3},         {"jc_B", 2e4}, {"jc_n", 0.4},
                   {"jc_C", 0.05},        {"jc_m", 1.2}, {"melt_temperature", 1500},
                   {"specific_heat", 450}};

// Linear hardening and Johnson-Cook: (a) elastic inside, (b) on the surface after the return,
// (c) surface points fixed, (d) eps_p non-decreasing; volume stays elastic.
TEST(MpmVonMises, ReturnMapProperties) {
  std::mt19937_64 rng(41);
  const double sy0 = 5e3, H = 1e4;
  for (const bool jc : {false, true}) {
    const auto m = jc ? make("von_mises", kJcKeys)
                      : make("von_mises", {{"yield_stress", sy0}, {"hardening", H}});
    const double mu = mu_of(*m), lambda = lambda_of(*m);
    const double dt = 1e-3;
    auto flow = [&](double eps_p, double rate, double T) {
      return jc ? kJc.flow(eps_p, rate, T) : sy0 + H * eps_p;
    };
    int inside = 0, outside = 0;
    for (int trial = 0; trial < 400; ++trial) {
      Mat3 F = random_F(rng, -0.02, 0.02);
      const Mat3 F0 = F;
      State st = initial_state(*m);
      st.s[0] = 0.05 * (trial % 3);  // some prior plastic strain
      st.s[1] = 294 + 100 * (trial % 4);
      const State st0 = st;
      const Mat3 trial_tau = hencky_tau_ref(F, mu, lambda);
      const double f_trial = norm(dev(trial_tau)) - kSqrt23 * flow(st.s[0], 0, st.s[1]);
      const Mat3 tau = update(*m, F, st, dt);
      const Mat3 ref = hencky_tau_ref(F, mu, lambda);
      EXPECT_LE(max_abs_diff(tau, ref), 1e-9 * norm(ref));
      EXPECT_GE(st.s[0], st0.s[0]);
      EXPECT_NEAR(trace(ref), trace(trial_tau), 1e-9 * norm(trial_tau));  // elastic volume
      EXPECT_NEAR(gen4d::materials::det(F), gen4d::materials::det(F0), 1e-13);
      const double scale = kSqrt23 * flow(st.s[0], st.s[2], st0.s[1]);
      if (f_trial < -1e-9 * scale) {
        ++inside;
        EXPECT_EQ(max_abs_diff(F, F0), 0.0);
        for (int k = 0; k < mpm::kStateSize; ++k) EXPECT_EQ(st.s[k], st0.s[k]);
      } else if (f_trial > 1e-9 * scale) {
        ++outside;
        EXPECT_GT(st.s[0], st0.s[0]);
        EXPECT_NEAR(st.s[2], (st.s[0] - st0.s[0]) / dt, 1e-9 * st.s[2]);
        // On the surface of the new state (flow stress at the new eps_p and rate).
        EXPECT_NEAR(norm(dev(ref)), kSqrt23 * flow(st.s[0], st.s[2], st0.s[1]), 1e-9 * scale);
        // The projection is radial: dev tau keeps its direction.
        const Mat3 a = dev(ref), b = dev(trial_tau);
        EXPECT_NEAR(gen4d::materials::frobenius_dot(a, b), norm(a) * norm(b),
                    1e-9 * norm(a) * norm(b));
        // Consistency: updating the returned point again changes nothing (linear hardening).
        // With Johnson-Cook the returned point lies on the rate-raised surface, above the
        // zero-rate one, so holding F relaxes it (viscoplastically): eps_p still only grows and
        // the stress only drops. Static surface points are checked in SurfacePointsAreFixed.
        Mat3 G = F;
        State again = st;
        const Mat3 tau2 = update(*m, G, again, dt);
        if (!jc) {
          EXPECT_LE(max_abs_diff(G, F), 1e-12);
          EXPECT_NEAR(again.s[0], st.s[0], 1e-12);
        } else {
          EXPECT_GE(again.s[0], st.s[0]);
          EXPECT_LE(norm(dev(tau2)), norm(dev(tau)) * (1 + 1e-12));
        }
      }
    }
    EXPECT_GT(inside, 20);
    EXPECT_GT(outside, 20);
  }
}

// Points built exactly on the static (zero-rate) surface map to themselves.
TEST(MpmVonMises, SurfacePointsAreFixed) {
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u(-1, 1);
  const double sy0 = 5e3, H = 1e4;
  for (const bool jc : {false, true}) {
    const auto m = jc ? make("von_mises", kJcKeys)
                      : make("von_mises", {{"yield_stress", sy0}, {"hardening", H}});
    const double mu = mu_of(*m);
    for (int trial = 0; trial < 100; ++trial) {
      const double eps_p = 0.1 * (u(rng) + 1), T = 294 + 300 * (u(rng) + 1);
      const double flow = jc ? kJc.flow(eps_p, 0, T) : sy0 + H * eps_p;
      Eigen::Vector3d d(u(rng), u(rng), u(rng));
      d -= Eigen::Vector3d::Constant(d.sum() / 3);
      d.normalize();
      const Eigen::Vector3d e =
          Eigen::Vector3d::Constant(0.01 * u(rng)) + kSqrt23 * flow / (2 * mu) * d;
      Mat3 F = random_rotation(rng) * diag(std::exp(e[0]), std::exp(e[1]), std::exp(e[2])) *
               random_rotation(rng);
      const Mat3 F0 = F;
      State st{{eps_p, T, 0, 0}};
      update(*m, F, st, 1e-3);
      EXPECT_LE(max_abs_diff(F, F0), 1e-12);
      EXPECT_NEAR(st.s[0], eps_p, 1e-12);
      EXPECT_NEAR(st.s[1], T, 1e-9);
    }
  }
}

// Uniaxial stress (lateral stretch solved for tau_22 = tau_33 = 0) with linear hardening follows
// sigma = E eps below sigma_y0 / E and sigma = E (sigma_y0 + H eps) / (E + H) above, in Kirchhoff
// stress and logarithmic strain, with eps_p = eps - sigma / E.
TEST(MpmVonMises, UniaxialLinearHardeningCurve) {
  const double E = 2e8, sy0 = 2e5, H = 1e7;
  const auto m = mpm::make_material(deck("von_mises",
                                         {{"youngs_modulus", E},
                                          {"poisson_ratio", 0.3},
                                          {"density", 7800},
                                          {"yield_stress", sy0},
                                          {"hardening", H}},
                                         false));
  Mat3 F = identity();
  State st = initial_state(*m);
  const double de = 5e-5;
  double eps = 0, max_err = 0;
  int plastic_steps = 0;
  double eps_p_peak = 0;
  for (int step = 0; step < 310; ++step) {
    const double sign = step < 300 ? 1.0 : -1.0;  // load, then unload elastically
    // Secant on the lateral log-strain increment for tau_22 = 0 (exact: piecewise linear).
    auto lateral_stress = [&](double dl, Mat3& Fout, State& sout, Mat3& tau) {
      Fout = diag(std::exp(sign * de), std::exp(dl), std::exp(dl)) * F;
      sout = st;
      tau = update(*m, Fout, sout, 1e-3);
      return tau(1, 1);
    };
    Mat3 Fa, tau;
    State sa;
    double x0 = -0.3 * sign * de, x1 = -0.5 * sign * de;
    double f0 = lateral_stress(x0, Fa, sa, tau), f1 = lateral_stress(x1, Fa, sa, tau);
    for (int it = 0; it < 50 && std::fabs(f1) > 1e-10 * sy0 && f1 != f0; ++it) {
      const double x2 = x1 - f1 * (x1 - x0) / (f1 - f0);
      x0 = x1;
      f0 = f1;
      x1 = x2;
      f1 = lateral_stress(x1, Fa, sa, tau);
    }
    ASSERT_LE(std::fabs(f1), 1e-8 * sy0);
    EXPECT_NEAR(tau(2, 2), 0.0, 1e-8 * sy0);
    F = Fa;
    if (sa.s[0] > st.s[0]) ++plastic_steps;
    st = sa;
    eps += sign * de;
    const double sigma = tau(0, 0);
    double expected;
    if (step < 300) {
      expected = eps <= sy0 / E ? E * eps : E * (sy0 + H * eps) / (E + H);
    } else {  // elastic unloading from the peak
      const double peak = 300 * de;
      expected = E * (sy0 + H * peak) / (E + H) - E * (peak - eps);
    }
    max_err = std::max(max_err, std::fabs(sigma - expected));
    if (step < 300) {
      EXPECT_NEAR(st.s[0], std::max(0.0, eps - sigma / E), 1e-12);
      eps_p_peak = st.s[0];
    } else {
      EXPECT_EQ(st.s[0], eps_p_peak);  // unloading is elastic
    }
  }
  EXPECT_LE(max_err, 1e-8 * sy0);
  EXPECT_GT(plastic_steps, 200);
}

// Johnson-Cook: the returned flow stress is the formula at the new eps_p, rate and temperature;
// it rises with rate and falls with temperature, and the heating equals the plastic work.
TEST(MpmVonMises, JohnsonCookRateTemperatureAndHeating) {
  const auto m = make("von_mises", kJcKeys);
  const double rho = 1000, cp = 450, chi = 0.9;
  const Mat3 Ftrial = diag(std::exp(0.03), std::exp(-0.012), std::exp(-0.015));
  auto run = [&](double dt, double T, double eps_p0, double& flow, State& st) {
    Mat3 F = Ftrial;
    st = State{{eps_p0, T, 0, 0}};
    const Mat3 tau = update(*m, F, st, dt);
    flow = norm(dev(tau)) / kSqrt23;
    // The formula at the returned state (temperature of the start of the step).
    EXPECT_NEAR(flow, kJc.flow(st.s[0], st.s[2], T), 1e-9 * flow);
    EXPECT_NEAR(st.s[2], (st.s[0] - eps_p0) / dt, 1e-9 * st.s[2]);
    // Adiabatic heating = taylor_quinney * plastic work / (rho c).
    EXPECT_NEAR(st.s[1] - T, chi * flow * (st.s[0] - eps_p0) / (rho * cp),
                1e-8 * (st.s[1] - T) + 1e-300);
    EXPECT_GT(st.s[0], eps_p0);
  };
  double slow, fast, hot, cold, hardened;
  State a, b, c, d, e;
  run(1e-1, 294, 0, slow, a);
  run(1e-6, 294, 0, fast, b);
  EXPECT_GT(b.s[2], a.s[2]);
  EXPECT_GT(fast, slow);
  run(1e-3, 294, 0.02, cold, c);
  run(1e-3, 900, 0.02, hot, d);
  EXPECT_LT(hot, cold);
  run(1e-3, 294, 0.3, hardened, e);
  EXPECT_GT(hardened, cold);
  // At or above the melt temperature the flow stress is zero: no deviatoric stress remains.
  double molten;
  State f;
  Mat3 F = Ftrial;
  f = State{{0, 1600, 0, 0}};
  const Mat3 tau = update(*m, F, f, 1e-3);
  molten = norm(dev(tau));
  EXPECT_LE(molten, 1e-9 * m->youngs_modulus());
  EXPECT_EQ(f.s[1], 1600);  // no work, no heating
}

// =============================================================================================
// Herschel-Bulkley

struct HbCase {
  double tau_y, K, n;
};

TEST(MpmHerschelBulkley, ReturnMapProperties) {
  std::mt19937_64 rng(51);
  for (const HbCase& c :
       {HbCase{2e3, 50, 0.6}, HbCase{2e3, 50, 1.0}, HbCase{1e3, 10, 1.7}, HbCase{2e3, 0, 1.0}}) {
    const auto m = make("herschel_bulkley",
                        {{"yield_stress", c.tau_y}, {"consistency", c.K}, {"flow_index", c.n}});
    const double mu = mu_of(*m), lambda = lambda_of(*m);
    int inside = 0, outside = 0;
    for (int trial = 0; trial < 300; ++trial) {
      const double dt = trial % 2 ? 1e-3 : 1e-5;
      Mat3 F = random_F(rng, -0.006, 0.006);
      const Mat3 F0 = F;
      State st{{0.1 * (trial % 3), 0, 0, 0}};
      const State st0 = st;
      const Mat3 trial_tau = hencky_tau_ref(F, mu, lambda);
      const double f_trial = norm(dev(trial_tau)) / kSqrt2 - c.tau_y;
      const Mat3 tau = update(*m, F, st, dt);
      const Mat3 ref = hencky_tau_ref(F, mu, lambda);
      EXPECT_LE(max_abs_diff(tau, ref), 1e-9 * norm(ref));
      EXPECT_GE(st.s[0], st0.s[0]);
      EXPECT_NEAR(trace(ref), trace(trial_tau), 1e-9 * norm(trial_tau));
      if (f_trial < -1e-9 * c.tau_y) {
        ++inside;
        EXPECT_EQ(max_abs_diff(F, F0), 0.0);
        EXPECT_EQ(st.s[0], st0.s[0]);
      } else if (f_trial > 1e-9 * c.tau_y) {
        ++outside;
        // On the rate-dependent surface: |s|/sqrt(2) = tau_y + K gamma_dot_p^n.
        const double rate = (st.s[0] - st0.s[0]) / dt;
        const double flow = c.tau_y + c.K * std::pow(rate, c.n);
        EXPECT_NEAR(norm(dev(ref)) / kSqrt2, flow, 1e-9 * flow);
        EXPECT_GT(st.s[0], st0.s[0]);
        // Radial: dev tau keeps its direction.
        const Mat3 a = dev(ref), b = dev(trial_tau);
        EXPECT_NEAR(gen4d::materials::frobenius_dot(a, b), norm(a) * norm(b),
                    1e-9 * norm(a) * norm(b));
        // Updating again: with K = 0 (rate-independent) the returned point is on the static
        // surface and stays put; with K > 0 it lies above it (viscous overstress), so holding F
        // relaxes the stress further, with eps_p only growing. Points exactly on the static
        // surface are checked in SurfacePointsAreFixed.
        Mat3 G = F;
        State again = st;
        const Mat3 tau2 = update(*m, G, again, dt);
        if (c.K == 0) {
          EXPECT_LE(max_abs_diff(G, F), 1e-12);
          EXPECT_NEAR(again.s[0], st.s[0], 1e-12);
        } else {
          EXPECT_GT(again.s[0], st.s[0]);
          EXPECT_LT(norm(dev(tau2)), norm(dev(tau)));
          EXPECT_GE(norm(dev(tau2)) / kSqrt2, c.tau_y * (1 - 1e-12));
        }
      }
    }
    EXPECT_GT(inside, 20);
    EXPECT_GT(outside, 20);
  }
}

// Points built exactly on the static surface |s| / sqrt(2) = tau_y map to themselves.
TEST(MpmHerschelBulkley, SurfacePointsAreFixed) {
  std::mt19937_64 rng(52);
  std::uniform_real_distribution<double> u(-1, 1);
  const double tau_y = 2e3;
  const auto m =
      make("herschel_bulkley", {{"yield_stress", tau_y}, {"consistency", 50}, {"flow_index", 0.6}});
  const double mu = mu_of(*m);
  for (int trial = 0; trial < 100; ++trial) {
    Eigen::Vector3d d(u(rng), u(rng), u(rng));
    d -= Eigen::Vector3d::Constant(d.sum() / 3);
    d.normalize();
    // |s| = 2 mu |dev e| = sqrt(2) tau_y.
    const Eigen::Vector3d e =
        Eigen::Vector3d::Constant(0.01 * u(rng)) + kSqrt2 * tau_y / (2 * mu) * d;
    Mat3 F = random_rotation(rng) * diag(std::exp(e[0]), std::exp(e[1]), std::exp(e[2])) *
             random_rotation(rng);
    const Mat3 F0 = F;
    State st{{0.3, 0, 0, 0}};
    update(*m, F, st, 1e-3);
    EXPECT_LE(max_abs_diff(F, F0), 1e-12);
    EXPECT_NEAR(st.s[0], 0.3, 1e-12);
  }
}

// Steady simple shear L = gamma_dot e1 (x) e2: tau_12 -> tau_y + K gamma_dot^n, and the plastic
// shear rate -> gamma_dot.
TEST(MpmHerschelBulkley, SimpleShearFlowStress) {
  for (const HbCase& c :
       {HbCase{10, 2, 1.0}, HbCase{10, 2, 0.5}, HbCase{10, 2, 1.5}, HbCase{0, 3, 0.7}}) {
    const auto m = mpm::make_material(deck("herschel_bulkley",
                                           {{"youngs_modulus", 2.6e6},
                                            {"poisson_ratio", 0.3},
                                            {"density", 1000},
                                            {"yield_stress", c.tau_y},
                                            {"consistency", c.K},
                                            {"flow_index", c.n}},
                                           false));
    for (const double gamma_dot : {0.5, 4.0}) {
      const double dt = 1e-8;
      Mat3 dF = identity();
      dF(0, 1) = gamma_dot * dt;
      Mat3 F = identity(), tau{};
      State st{};
      double last = 0;
      for (int step = 0; step < 20000; ++step) {
        F = dF * F;
        last = st.s[0];
        tau = update(*m, F, st, dt);
      }
      const double expected = c.tau_y + c.K * std::pow(gamma_dot, c.n);
      EXPECT_NEAR(tau(0, 1), expected, 1e-6 * expected) << c.n << " " << gamma_dot;
      EXPECT_NEAR((st.s[0] - last) / dt, gamma_dot, 1e-6 * gamma_dot);
    }
  }
}

// One update: the flow law holds exactly at the plastic rate the update produced.
TEST(MpmHerschelBulkley, SingleStepFlowLaw) {
  const auto m =
      make("herschel_bulkley", {{"yield_stress", 100}, {"consistency", 40}, {"flow_index", 0.45}});
  const double dt = 2e-4;
  for (const double g : {1e-3, 1e-2, 5e-2}) {
    Mat3 F = identity();
    F(0, 1) = g;
    State st{};
    const Mat3 tau = update(*m, F, st, dt);
    const double rate = st.s[0] / dt;
    const double flow = 100 + 40 * std::pow(rate, 0.45);
    EXPECT_NEAR(norm(dev(tau)) / kSqrt2, flow, 1e-9 * flow);
  }
}

// =============================================================================================
// Fracture

TEST(MpmFracture, UndamagedIsFixedCorotated) {
  std::mt19937_64 rng(61);
  const auto fr = make("fracture", {{"fracture_strain", 0.5}, {"failure_strain", 0.8}});
  const auto fcr = make("fixed_corotated");
  for (int trial = 0; trial < 50; ++trial) {
    Mat3 F = random_F(rng, -0.3, 0.3);
    State st = initial_state(*fr);
    const Mat3 tau = update(*fr, F, st, 1e-3);
    EXPECT_LE(max_abs_diff(tau, stress_of(*fcr, F, {})), 1e-12 * norm(tau));
    EXPECT_EQ(st.s[0], 0.0);
  }
}

TEST(MpmFracture, DamageIsMonotoneAndFollowsTheHistory) {
  std::mt19937_64 rng(62);
  std::uniform_real_distribution<double> u(-0.02, 0.02);
  const double ec = 0.02, ef = 0.08;
  const auto m = make("fracture", {{"fracture_strain", ec}, {"failure_strain", ef}});
  Mat3 F = identity();
  State st = initial_state(*m);
  double d_last = 0, h_last = 0;
  for (int step = 0; step < 400; ++step) {
    Mat3 dF = identity();
    for (double& x : dF.a) x += u(rng);
    F = dF * F;
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(to_eigen(F));
    const double e_max = std::log(svd.singularValues()[0]);
    update(*m, F, st, 1e-3);
    EXPECT_GE(st.s[0], d_last);
    EXPECT_GE(st.s[1], h_last);
    EXPECT_NEAR(st.s[1], std::max(h_last, e_max), 1e-12);
    EXPECT_NEAR(st.s[0], std::clamp((st.s[1] - ec) / (ef - ec), 0.0, 1.0), 1e-12);
    d_last = st.s[0];
    h_last = st.s[1];
  }
  EXPECT_GT(d_last, 0.0);
}

TEST(MpmFracture, BrokenMaterialCarriesCompressionOnly) {
  const auto m = make("fracture", {{"fracture_strain", 0.02}, {"failure_strain", 0.05}});
  const auto fcr = make("fixed_corotated");
  std::mt19937_64 rng(63);
  const Mat3 Q = random_rotation(rng);
  const Mat3 Qt = gen4d::materials::transpose(Q);
  // Pull past failure_strain: d = 1, the tensile stress is gone.
  Mat3 F = Q * diag(1.1, 1.0, 1.0);
  State st = initial_state(*m);
  Mat3 tau = update(*m, F, st, 1e-3);
  EXPECT_EQ(st.s[0], 1.0);
  EXPECT_LE(norm(tau), 1e-12 * m->youngs_modulus());
  // Half-way: tension scaled by (1 - d).
  State half = initial_state(*m);
  Mat3 Fh = Q * diag(std::exp(0.035), 1.0, 1.0);
  tau = update(*m, Fh, half, 1e-3);
  EXPECT_NEAR(half.s[0], 0.5, 1e-12);
  EXPECT_LE(max_abs_diff(tau, 0.5 * stress_of(*fcr, Fh, {})), 1e-9 * norm(tau));
  // Compression afterwards: full stiffness.
  for (const Mat3& G : {diag(0.95, 0.95, 0.95), diag(0.9, 0.97, 0.99)}) {
    F = Q * G * Qt;
    tau = update(*m, F, st, 1e-3);
    const Mat3 full = stress_of(*fcr, F, {});
    EXPECT_EQ(st.s[0], 1.0);
    EXPECT_LE(max_abs_diff(tau, full), 1e-12 * norm(full));
    EXPECT_LT(trace(tau), 0.0);
  }
  // Mixed: compression along one axis kept, tension along the others dropped.
  F = diag(1.05, 1.05, 0.8);
  tau = update(*m, F, st, 1e-3);
  const Mat3 full = stress_of(*fcr, F, {});
  EXPECT_NEAR(tau(2, 2), full(2, 2), 1e-12 * norm(full));
  EXPECT_LT(tau(2, 2), 0.0);
  EXPECT_NEAR(tau(0, 0), std::min(full(0, 0), 0.0), 1e-12 * norm(full));
  EXPECT_NEAR(tau(1, 1), std::min(full(1, 1), 0.0), 1e-12 * norm(full));
  // stress() agrees with update() and leaves the state alone.
  const State before = st;
  EXPECT_LE(max_abs_diff(stress_of(*m, F, st), tau), 1e-12 * norm(full));
  for (int k = 0; k < mpm::kStateSize; ++k) EXPECT_EQ(st.s[k], before.s[k]);
}

// A 1D bar of segments (uniaxial F = diag(l / l0, 1, 1), nu = 0), one end fixed, the other pulled
// at constant speed by explicit dynamics: the fracture bar must break into pieces (broken segments
// carry exactly no force and open up by about the pulled distance, nothing reaches the fixed
// end), while the same bar with fixed-corotated elasticity stays in one piece under tension.
struct BarResult {
  std::vector<State> state;
  std::vector<double> x, force;
};

BarResult pull_bar(const mpm::Material& m, double v_pull, double t_end) {
  const int N = 40;
  const double L = 1.0, l0 = L / N, A = 1e-4;
  const double c = m.wave_speed(), dt = 0.2 * l0 / c;
  BarResult r;
  r.x.resize(N + 1);
  std::vector<double> v(N + 1, 0.0);
  for (int i = 0; i <= N; ++i) r.x[i] = i * l0;
  r.state.assign(N, initial_state(m));
  r.force.assign(N, 0.0);
  const double node_mass = m.density() * A * l0;
  const int steps = static_cast<int>(t_end / dt);
  for (int step = 0; step < steps; ++step) {
    for (int s = 0; s < N; ++s) {
      Mat3 F = diag((r.x[s + 1] - r.x[s]) / l0, 1, 1);
      const Mat3 tau = update(m, F, r.state[s], dt);
      r.force[s] = A * tau(0, 0) / F(0, 0);  // P_11 times the rest area
    }
    for (int i = 1; i < N; ++i) v[i] += dt * (r.force[i] - r.force[i - 1]) / node_mass;
    v[0] = 0;
    v[N] = v_pull;
    for (int i = 0; i <= N; ++i) r.x[i] += dt * v[i];
  }
  return r;
}

TEST(MpmFracture, PulledBarSeparates) {
  const double E = 1e5, A = 1e-4, v_pull = 0.5, t_end = 1.0, l0 = 1.0 / 40;
  const Keys common{{"youngs_modulus", E}, {"poisson_ratio", 0}, {"density", 1000}};
  Keys fracture_keys = common;
  fracture_keys.push_back({"fracture_strain", 0.05});
  fracture_keys.push_back({"failure_strain", 0.1});
  const auto fr = mpm::make_material(deck("fracture", fracture_keys, false));
  const auto elastic = mpm::make_material(deck("fixed_corotated", common, false));

  const BarResult broken_bar = pull_bar(*fr, v_pull, t_end);
  int broken = 0;
  double gap = 0;
  for (std::size_t s = 0; s < broken_bar.state.size(); ++s) {
    if (broken_bar.state[s].s[0] != 1.0) continue;
    ++broken;
    EXPECT_EQ(broken_bar.force[s], 0.0);
    gap += broken_bar.x[s + 1] - broken_bar.x[s] - l0;
  }
  EXPECT_GE(broken, 1);
  EXPECT_LT(broken, 40);
  // The opening takes up most of the pulled distance (the rest is elastic ringing of pieces).
  EXPECT_GT(gap, 0.7 * v_pull * t_end);

  const BarResult whole = pull_bar(*elastic, v_pull, t_end);
  // Held together: the fixed end feels the tension of a ~50 % stretched bar.
  EXPECT_GT(whole.force[0], 0.2 * E * A);
}

// =============================================================================================
// Registry errors

std::string input_error(const mpm::MaterialParams& p) {
  try {
    mpm::make_material(p);
  } catch (const gen4d::InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no InputError for model " << p.model;
  return "";
}

TEST(MpmMaterialRegistry, UnknownModel) {
  const std::string msg = input_error(deck("jelly", {}));
  EXPECT_NE(msg.find("test.toml:1"), std::string::npos) << msg;
  EXPECT_NE(msg.find("material.model"), std::string::npos) << msg;
  EXPECT_NE(msg.find("jelly"), std::string::npos) << msg;
  EXPECT_NE(msg.find("von_mises"), std::string::npos) << msg;  // lists the known models
  EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  EXPECT_NE(input_error(deck("", {})).find("material.model"), std::string::npos);
  EXPECT_THROW(mpm::material_keys("jelly"), gen4d::InputError);
}

TEST(MpmMaterialRegistry, ForeignKey) {
  auto p = deck("neo_hookean", {{"friction_angle", 30}});
  std::string msg = input_error(p);
  EXPECT_NE(msg.find("test.toml:5: material.friction_angle"), std::string::npos) << msg;
  EXPECT_NE(msg.find("neo_hookean"), std::string::npos) << msg;
  msg = input_error(deck("drucker_prager", {{"friction_angle", 30}, {"yield_stress", 1}}));
  EXPECT_NE(msg.find("material.yield_stress"), std::string::npos) << msg;
}

TEST(MpmMaterialRegistry, MissingKey) {
  struct Case {
    const char* model;
    Keys keys;
    const char* missing;
  };
  for (const Case& c : {Case{"drucker_prager", {}, "friction_angle"},
                        Case{"von_mises", {{"hardening", 1}}, "yield_stress"},
                        Case{"herschel_bulkley", {{"yield_stress", 1}}, "consistency"},
                        Case{"herschel_bulkley", {{"consistency", 1}}, "yield_stress"},
                        Case{"fracture", {{"fracture_strain", 0.1}}, "failure_strain"},
                        Case{"fracture", {{"failure_strain", 0.1}}, "fracture_strain"}}) {
    const std::string msg = input_error(deck(c.model, c.keys));
    EXPECT_NE(msg.find(std::string("material.") + c.missing), std::string::npos) << msg;
    EXPECT_NE(msg.find("required"), std::string::npos) << msg;
    EXPECT_NE(msg.find("test.toml"), std::string::npos) << msg;
  }
  for (const char* common : {"youngs_modulus", "poisson_ratio", "density"}) {
    auto p = deck("fixed_corotated", {});
    p.values.erase(common);
    p.where.erase(common);
    const std::string msg = input_error(p);
    EXPECT_NE(msg.find(std::string("test.toml: material.") + common), std::string::npos) << msg;
  }
}

TEST(MpmMaterialRegistry, BadValues) {
  struct Case {
    const char* model;
    Keys keys;
    const char* key;
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<Case> cases = {
      {"fixed_corotated", {{"youngs_modulus", -1}}, "youngs_modulus"},
      {"fixed_corotated", {{"youngs_modulus", 0}}, "youngs_modulus"},
      {"stvk_hencky", {{"poisson_ratio", 0.5}}, "poisson_ratio"},
      {"stvk_hencky", {{"poisson_ratio", -1}}, "poisson_ratio"},
      {"neo_hookean", {{"density", 0}}, "density"},
      {"neo_hookean", {{"density", nan}}, "density"},
      {"drucker_prager", {{"friction_angle", 90}}, "friction_angle"},
      {"drucker_prager", {{"friction_angle", -1}}, "friction_angle"},
      {"drucker_prager", {{"friction_angle", 30}, {"cohesion", -1}}, "cohesion"},
      {"von_mises", {{"yield_stress", -1}}, "yield_stress"},
      {"von_mises", {{"yield_stress", 1}, {"hardening", -1}}, "hardening"},
      {"von_mises", {{"yield_stress", 1}, {"jc_B", 1}}, "jc_B"},
      {"von_mises", {{"yield_stress", 1}, {"jc_A", 1}}, "yield_stress"},
      {"von_mises", {{"jc_A", -1}}, "jc_A"},
      {"von_mises", {{"jc_A", 1}, {"jc_n", 0}}, "jc_n"},
      {"von_mises", {{"jc_A", 1}, {"jc_m", 0}}, "jc_m"},
      {"von_mises", {{"jc_A", 1}, {"jc_C", -0.1}}, "jc_C"},
      {"von_mises", {{"jc_A", 1}, {"melt_temperature", 200}}, "melt_temperature"},
      {"von_mises", {{"yield_stress", 1}, {"specific_heat", 0}}, "specific_heat"},
      {"von_mises", {{"yield_stress", 1}, {"taylor_quinney", 1.5}}, "taylor_quinney"},
      {"von_mises", {{"yield_stress", 1}, {"reference_strain_rate", 0}}, "reference_strain_rate"},
      {"von_mises", {{"yield_stress", 1}, {"initial_temperature", -3}}, "initial_temperature"},
      {"herschel_bulkley", {{"yield_stress", -1}, {"consistency", 1}}, "yield_stress"},
      {"herschel_bulkley", {{"yield_stress", 1}, {"consistency", -1}}, "consistency"},
      {"herschel_bulkley",
       {{"yield_stress", 1}, {"consistency", 1}, {"flow_index", 0}},
       "flow_index"},
      {"fracture", {{"fracture_strain", -0.1}, {"failure_strain", 0.2}}, "fracture_strain"},
      {"fracture", {{"fracture_strain", 0.2}, {"failure_strain", 0.2}}, "failure_strain"},
  };
  for (const Case& c : cases) {
    const std::string msg = input_error(deck(c.model, c.keys));
    EXPECT_NE(msg.find(std::string("material.") + c.key), std::string::npos)
        << c.model << " " << c.key << ": " << msg;
    EXPECT_NE(msg.find("test.toml:"), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  }
}

// A model registered from outside the library is found by name; duplicates are refused.
TEST(MpmMaterialRegistry, ExternalRegistration) {
  class Null final : public mpm::Material {
   public:
    std::string name() const override { return "test_null"; }
    std::vector<std::string> state_names() const override { return {}; }
    void update(std::size_t n, double*, double*, double* tau, double) const override {
      std::fill(tau, tau + 9 * n, 0.0);
    }
    void stress(std::size_t n, const double*, const double*, double* tau) const override {
      std::fill(tau, tau + 9 * n, 0.0);
    }
    double wave_speed() const override { return 1; }
  };
  EXPECT_TRUE(mpm::register_material({"test_null", {"knob"}, [](const mpm::MaterialParams&) {
                                        return std::make_unique<Null>();
                                      }}));
  EXPECT_EQ(mpm::make_material(deck("test_null", {{"knob", 1}}))->name(), "test_null");
  EXPECT_THROW(
      mpm::register_material(
          {"von_mises", {}, [](const mpm::MaterialParams&) { return std::make_unique<Null>(); }}),
      std::logic_error);
}

}  // namespace
