// Constitutive models: stress = energy gradient, rest/rotation behaviour, Lame conversion,
// projection stiffness bounds and the material registry.
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/Error.hpp"
#include "materials/Arap.hpp"
#include "materials/FixedCorotated.hpp"
#include "materials/LinearElastic.hpp"
#include "materials/NeoHookean.hpp"
#include "materials/StVK.hpp"
#include "materials/Registry.hpp"

namespace gm = gen4d::materials;
using gm::Mat3;
using gm::Vec3;

namespace {

Mat3 random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> normal;
  const Eigen::Matrix3d R = Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng))
                                .normalized()
                                .toRotationMatrix();
  Mat3 M;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) M(r, c) = R(r, c);
  return M;
}

// I + uniform perturbation, mirrored when `inverted`. The signed polar rotation (hence P) jumps
// where |sigma_1| = |sigma_2| on inverted F, so samples keep those magnitudes apart for the
// finite differences to be meaningful.
Mat3 random_deformation(std::mt19937_64& rng, bool inverted) {
  std::uniform_real_distribution<double> uniform(-0.6, 0.6);
  while (true) {
    Mat3 F = gm::identity3();
    for (double& x : F.a) x += uniform(rng);
    if (inverted)
      for (int c = 0; c < 3; ++c) F(2, c) = -F(2, c);
    Mat3 U, V;
    Vec3 s;
    gm::svd3(F, U, s, V);
    if ((gm::det(F) < 0) == inverted && std::abs(s[1]) - std::abs(s[2]) > 0.05 &&
        std::abs(s[2]) > 0.05)
      return F;
  }
}

template <class M>
Mat3 finite_difference_pk1(const M& material, const Mat3& F, double h) {
  Mat3 P;
  for (int i = 0; i < 9; ++i) {
    Mat3 plus = F, minus = F;
    plus.a[i] += h;
    minus.a[i] -= h;
    P.a[i] = (material.energy(plus) - material.energy(minus)) / (2 * h);
  }
  return P;
}

// Largest eigenvalue of the symmetrised 9x9 dP/dF by central differences of the stress.
template <class M>
double max_stiffness_eigenvalue(const M& material, const Mat3& F) {
  const double h = 1e-6;
  Eigen::Matrix<double, 9, 9> H;
  for (int j = 0; j < 9; ++j) {
    Mat3 plus = F, minus = F;
    plus.a[j] += h;
    minus.a[j] -= h;
    const Mat3 dP = material.pk1(plus) - material.pk1(minus);
    for (int i = 0; i < 9; ++i) H(i, j) = dP.a[i] / (2 * h);
  }
  const Eigen::Matrix<double, 9, 9> sym = 0.5 * (H + H.transpose());
  return Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 9, 9>>(sym).eigenvalues().maxCoeff();
}

template <class M>
void expect_pk1_is_energy_gradient(const M& material, const char* what) {
  std::mt19937_64 rng(11);
  double worst = 0;
  for (int i = 0; i < 400; ++i) {
    const Mat3 F = random_deformation(rng, i % 2 == 1);
    const Mat3 P = material.pk1(F);
    const Mat3 fd = finite_difference_pk1(material, F, 1e-6);
    worst = std::max(worst, gm::frobenius_norm(P - fd) / gm::frobenius_norm(P));
  }
  std::printf("[ materials ] %s: worst |P - FD| / |P| = %.2e\n", what, worst);
  EXPECT_LT(worst, 1e-6) << what;
  // The solver's fused call (one SVD) must equal the two separate calls bit for bit.
  for (int i = 0; i < 100; ++i) {
    const Mat3 F = random_deformation(rng, i % 2 == 1);
    Mat3 P;
    const double psi = material.energy_and_pk1(F, P);
    EXPECT_EQ(psi, material.energy(F)) << what;
    const Mat3 Pref = material.pk1(F);
    for (int a = 0; a < 9; ++a) EXPECT_EQ(P.a[a], Pref.a[a]) << what;
  }
}

template <class M>
void expect_rest_and_rotation_free(const M& material, double modulus, const char* what,
                                   double energy_tolerance = 1e-24) {
  EXPECT_EQ(material.energy(gm::identity3()), 0.0) << what;
  EXPECT_EQ(gm::frobenius_norm(material.pk1(gm::identity3())), 0.0) << what;
  std::mt19937_64 rng(12);
  for (int i = 0; i < 1000; ++i) {
    const Mat3 R = random_rotation(rng);
    EXPECT_LT(std::abs(material.energy(R)), energy_tolerance * modulus) << what;
    EXPECT_LT(gm::frobenius_norm(material.pk1(R)), 1e-13 * modulus) << what;
  }
}

// psi(Q F) = psi(F) and P(Q F) = Q P(F): frame indifference, also for inverted F.
template <class M>
void expect_frame_indifference(const M& material, const char* what) {
  std::mt19937_64 rng(13);
  for (int i = 0; i < 1000; ++i) {
    const Mat3 F = random_deformation(rng, i % 2 == 1);
    const Mat3 Q = random_rotation(rng);
    const double psi = material.energy(F);
    EXPECT_NEAR(material.energy(Q * F), psi, 1e-12 * psi) << what;
    const Mat3 P = material.pk1(F);
    EXPECT_LT(gm::frobenius_norm(material.pk1(Q * F) - Q * P), 1e-12 * gm::frobenius_norm(P))
        << what;
  }
}

}  // namespace

TEST(Materials, LameConversion) {
  const gm::Lame lame = gm::lame_from_young_poisson(1e6, 0.3);
  EXPECT_NEAR(lame.mu, 1e6 / 2.6, 1e-9);
  EXPECT_NEAR(lame.lambda, 0.3e6 / (1.3 * 0.4), 1e-9);
  // Cross-checks with the bulk modulus K = E / (3 (1 - 2 nu)) = lambda + 2 mu / 3 and back to E.
  EXPECT_NEAR(lame.lambda + 2 * lame.mu / 3, 1e6 / (3 * 0.4), 1e-6);
  EXPECT_NEAR(lame.mu * (3 * lame.lambda + 2 * lame.mu) / (lame.lambda + lame.mu), 1e6, 1e-6);
  const gm::Lame zero_nu = gm::lame_from_young_poisson(2.0, 0.0);
  EXPECT_DOUBLE_EQ(zero_nu.mu, 1.0);
  EXPECT_DOUBLE_EQ(zero_nu.lambda, 0.0);

  const auto corotated = gm::FixedCorotated::from_young_poisson(1e6, 0.3);
  EXPECT_DOUBLE_EQ(corotated.mu, lame.mu);
  EXPECT_DOUBLE_EQ(corotated.lambda, lame.lambda);
  EXPECT_DOUBLE_EQ(gm::Arap::from_young_poisson(1e6, 0.3).k, 2 * lame.mu);

  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (double E : {0.0, -1.0, nan, std::numeric_limits<double>::infinity()})
    EXPECT_THROW(gm::lame_from_young_poisson(E, 0.3), gen4d::InputError) << E;
  for (double nu : {0.5, -1.0, 0.7, nan})
    EXPECT_THROW(gm::lame_from_young_poisson(1e6, nu), gen4d::InputError) << nu;
  try {
    gm::lame_from_young_poisson(1e6, 0.5);
  } catch (const gen4d::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("poisson_ratio"), std::string::npos) << e.what();
  }
}

TEST(Materials, CorotatedStressIsEnergyGradient) {
  expect_pk1_is_energy_gradient(gm::FixedCorotated::from_young_poisson(1e6, 0.3), "corotated");
  expect_pk1_is_energy_gradient(gm::FixedCorotated::from_young_poisson(1e6, 0.45),
                                "corotated nu=0.45");
}

// The analytic stress Jacobian of the corotated law (the diagnose model's implicit tangent)
// against central differences of its stress, at rest, on stretched/rotated and on inverted F.
TEST(Materials, CorotatedStressJacobianMatchesFiniteDifferences) {
  for (double nu : {0.0, 0.3, 0.45}) {
    const auto material = gm::FixedCorotated::from_young_poisson(1e6, nu);
    std::mt19937_64 rng(16);
    double worst = 0;
    for (int s = 0; s < 201; ++s) {
      const Mat3 F = s == 0 ? gm::identity3() : random_deformation(rng, s % 2 == 0);
      double D[9][9];
      material.pk1_jacobian(F, D);
      const double h = 1e-6;
      double err = 0, scale = 0;
      for (int j = 0; j < 9; ++j) {
        Mat3 plus = F, minus = F;
        plus.a[j] += h;
        minus.a[j] -= h;
        const Mat3 dP = material.pk1(plus) - material.pk1(minus);
        for (int i = 0; i < 9; ++i) {
          const double fd = dP.a[i] / (2 * h);
          err = std::max(err, std::abs(D[i][j] - fd));
          scale = std::max(scale, std::abs(fd));
        }
      }
      worst = std::max(worst, err / scale);
    }
    std::printf("[ materials ] corotated nu=%.2f: worst |dP/dF - FD| / max|dP/dF| = %.2e\n", nu,
                worst);
    EXPECT_LT(worst, 1e-6) << nu;
  }
}

// The Newton polar iteration (the diagnose model's corotated stress) against the SVD's
// rotation: equal to rounding on stretched, sheared and rotated F; declined when inverted.
TEST(Materials, NewtonPolarRotationMatchesTheSvd) {
  std::mt19937_64 rng(17);
  double worst = 0;
  for (int s = 0; s < 400; ++s) {
    const bool inverted = s % 4 == 3;
    const Mat3 F =
        s == 0 ? gm::identity3() : random_deformation(rng, inverted) * random_rotation(rng);
    Mat3 R = gm::identity3();
    const bool ok = gm::polar_rotation_newton(F, R);
    EXPECT_EQ(ok, !inverted) << s;
    if (!ok) continue;
    worst = std::max(worst, gm::frobenius_norm(R - gm::polar_rotation(F)));
  }
  std::printf("[ materials ] Newton polar rotation: worst |R - R_svd| = %.2e\n", worst);
  EXPECT_LT(worst, 1e-13);
  Mat3 R = gm::identity3();
  EXPECT_FALSE(gm::polar_rotation_newton(gm::diag3(Vec3{{1, 1, 0}}), R));  // flat
  EXPECT_EQ(R.a[1], 0.0);                                                  // untouched
}

TEST(Materials, ArapStressIsEnergyGradient) {
  expect_pk1_is_energy_gradient(gm::Arap{3e5}, "arap");
}

TEST(Materials, CorotatedStressDefinedAtZeroVolume) {
  // cof(F) replaces J F^{-T}, so a flattened element gets a finite, restoring stress.
  const auto material = gm::FixedCorotated::from_young_poisson(1e6, 0.3);
  const Mat3 flat = gm::diag3(Vec3{{1, 1, 0}});
  const Mat3 P = material.pk1(flat);
  for (double x : P.a) EXPECT_TRUE(std::isfinite(x));
  EXPECT_LT(P(2, 2), 0.0);  // pushes the flattened axis back out: -lambda * cof_22 = -lambda
  EXPECT_NEAR(P(2, 2), -2 * material.mu - material.lambda, 1e-6);
  EXPECT_NEAR(material.energy(flat), material.mu + 0.5 * material.lambda, 1e-6);
}

TEST(Materials, RestAndRotationsAreStressFree) {
  expect_rest_and_rotation_free(gm::FixedCorotated::from_young_poisson(1e6, 0.3), 1e6, "corotated");
  expect_rest_and_rotation_free(gm::Arap{1e6}, 1e6, "arap");
}

TEST(Materials, FrameIndifference) {
  expect_frame_indifference(gm::FixedCorotated::from_young_poisson(1e6, 0.3), "corotated");
  expect_frame_indifference(gm::Arap{1e6}, "arap");
}

TEST(Materials, ProjectionStiffnessBoundsTheStressJacobian) {
  std::mt19937_64 rng(14);
  std::uniform_real_distribution<double> stretch(-gm::kProjectionDesignStretch,
                                                 gm::kProjectionDesignStretch);
  for (double nu : {-0.3, 0.0, 0.3, 0.45}) {
    const auto material = gm::FixedCorotated::from_young_poisson(1e6, nu);
    const double k = material.projection_stiffness();
    // At rest the dilation mode is 2 mu + 3 lambda, the deviatoric ones 2 mu.
    const double rest = max_stiffness_eigenvalue(material, gm::identity3());
    EXPECT_NEAR(rest, 2 * material.mu + std::max(3 * material.lambda, 0.0), 1e-6 * k) << nu;
    EXPECT_LE(rest, k) << nu;
    // Uniform stretch at the design limit: the bound is attained when lambda >= 0.
    const double a = 1 + gm::kProjectionDesignStretch;
    const double uniform = max_stiffness_eigenvalue(material, gm::diag3(Vec3{{a, a, a}}));
    EXPECT_LE(uniform, k * (1 + 1e-7)) << nu;
    if (nu >= 0) EXPECT_NEAR(uniform, k, 1e-6 * k) << nu;
    double worst_ratio = 0;
    for (int i = 0; i < 200; ++i) {
      const Vec3 s{{1 + stretch(rng), 1 + stretch(rng), 1 + stretch(rng)}};
      const Mat3 F = random_rotation(rng) * gm::diag3(s) * random_rotation(rng);
      worst_ratio = std::max(worst_ratio, max_stiffness_eigenvalue(material, F) / k);
    }
    std::printf(
        "[ materials ] corotated nu=%.2f: k = 2mu + %.3f lambda, max eig(dP/dF)/k = %.4f"
        " over |sigma-1| <= %.2f\n",
        nu, (k - 2 * material.mu) / (material.lambda != 0 ? material.lambda : 1), worst_ratio,
        gm::kProjectionDesignStretch);
    EXPECT_LE(worst_ratio, 1 + 1e-7) << nu;
  }
  const gm::Arap arap{1e6};
  std::mt19937_64 rng2(15);
  for (int i = 0; i < 100; ++i) {
    const Vec3 s{{1 + 3 * stretch(rng2), 1 + 3 * stretch(rng2), 1 + 3 * stretch(rng2)}};
    const Mat3 F = random_rotation(rng2) * gm::diag3(s) * random_rotation(rng2);
    EXPECT_LE(max_stiffness_eigenvalue(arap, F), arap.projection_stiffness() * (1 + 1e-7));
  }
}

TEST(Materials, LocalGlobalIterationConvergesMonotonically) {
  // One element with inertia m: minimise m/2 |F - Y|^2 + psi(F) by the projective-dynamics
  // iteration F <- (m Y + k p) / (m + k), p = F - P(F) / k. With k >= max eig(dP/dF) the
  // objective must decrease every step and the fixed point satisfy m (F - Y) + P(F) = 0.
  const auto material = gm::FixedCorotated::from_young_poisson(1e6, 0.4);
  const double k = material.projection_stiffness();
  const double m = 0.2 * k;
  std::mt19937_64 rng(16);
  for (int trial = 0; trial < 20; ++trial) {
    const Vec3 s{{1.08, 0.95, 1.03}};
    const Mat3 Y = random_rotation(rng) * gm::diag3(s) * random_rotation(rng);
    auto objective = [&](const Mat3& F) {
      const Mat3 d = F - Y;
      return 0.5 * m * gm::frobenius_dot(d, d) + material.energy(F);
    };
    // Evaluating psi rounds at about eps * k |F|^2; below that "decrease" has no meaning.
    const double rounding = 1e-15 * k * gm::frobenius_dot(Y, Y);
    Mat3 F = Y;
    double previous = objective(F);
    int iterations = 0;
    double residual = 0;
    for (; iterations < 500; ++iterations) {
      const Mat3 p = F - (1.0 / k) * material.pk1(F);
      F = (1.0 / (m + k)) * (m * Y + k * p);
      const double current = objective(F);
      ASSERT_LE(current, previous + rounding) << "trial " << trial << " step " << iterations;
      previous = current;
      residual = gm::frobenius_norm(m * (F - Y) + material.pk1(F)) / (m * gm::frobenius_norm(Y));
      if (residual < 1e-12) break;
    }
    EXPECT_LT(residual, 1e-12) << "trial " << trial;
  }
}

TEST(MaterialRegistry, BuildsByDeckName) {
  const auto names = gm::known_materials();
  EXPECT_NE(std::find(names.begin(), names.end(), "corotated"), names.end());
  EXPECT_NE(std::find(names.begin(), names.end(), "arap"), names.end());
  EXPECT_TRUE(std::is_sorted(names.begin(), names.end()));

  const gm::MaterialInstance corotated = gm::find_material("corotated").build(1e6, 0.3);
  const auto direct = gm::FixedCorotated::from_young_poisson(1e6, 0.3);
  EXPECT_EQ(corotated.name, "corotated");
  EXPECT_DOUBLE_EQ(corotated.projection_stiffness, direct.projection_stiffness());
  const Mat3 F = gm::diag3(Vec3{{1.1, 0.9, -0.8}});
  EXPECT_DOUBLE_EQ(corotated.energy(F), direct.energy(F));
  EXPECT_EQ(gm::frobenius_norm(corotated.pk1(F) - direct.pk1(F)), 0.0);

  const gm::MaterialInstance arap = gm::find_material("arap").build(1e6, 0.3);
  EXPECT_DOUBLE_EQ(arap.projection_stiffness, 2 * direct.mu);
  EXPECT_DOUBLE_EQ(arap.energy(F), gm::Arap{2 * direct.mu}.energy(F));

  EXPECT_THROW(gm::find_material("corotated").build(-1, 0.3), gen4d::InputError);
}

TEST(MaterialRegistry, UnknownNameListsKnownOnes) {
  try {
    gm::find_material("neohooken");
    FAIL() << "expected InputError";
  } catch (const gen4d::InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("unknown material 'neohooken'; known: "), std::string::npos) << what;
    EXPECT_NE(what.find("arap"), std::string::npos) << what;
    EXPECT_NE(what.find("corotated"), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
}

TEST(MaterialRegistry, RejectsDuplicateNames) {
  EXPECT_THROW(gm::register_material(gm::describe_material<gm::Arap>()), std::logic_error);
  EXPECT_THROW(gm::register_material(gm::MaterialDescriptor{"", nullptr}), std::logic_error);
}

namespace {
// Every hyperelastic law must reduce to linear elasticity with the deck's (E, nu) near rest:
// dP/dF at F = I equals mu (d_ik d_jl + d_il d_jk) + lambda d_ij d_kl.
template <class M>
void expect_linear_elasticity_at_rest(double E, double nu, const char* what) {
  const M material = M::from_young_poisson(E, nu);
  const gm::Lame l = gm::lame_from_young_poisson(E, nu);
  const double h = 1e-6;
  double worst = 0;
  for (int kl = 0; kl < 9; ++kl) {
    Mat3 plus = gm::identity3(), minus = gm::identity3();
    plus.a[kl] += h;
    minus.a[kl] -= h;
    const Mat3 dP = material.pk1(plus) - material.pk1(minus);
    const int k = kl / 3, ll = kl % 3;
    for (int ij = 0; ij < 9; ++ij) {
      const int i = ij / 3, j = ij % 3;
      const double c =
          l.mu * ((i == k && j == ll) + (i == ll && j == k)) + l.lambda * (i == j && k == ll);
      worst = std::max(worst, std::abs(dP.a[ij] / (2 * h) - c));
    }
  }
  std::printf("[ materials ] %s: |dP/dF(I) - C_linear| = %.2e (E = %.0e)\n", what, worst, E);
  EXPECT_LT(worst, 1e-6 * E) << what;
}

template <class M>
void expect_projection_stiffness_bounds(const M& material, double s, const char* what) {
  std::mt19937_64 rng(16);
  std::uniform_real_distribution<double> stretch(-s, s);
  const double k = material.projection_stiffness();
  double worst = 0;
  for (int i = 0; i < 200; ++i) {
    const Vec3 sv{{1 + stretch(rng), 1 + stretch(rng), 1 + stretch(rng)}};
    const Mat3 F = random_rotation(rng) * gm::diag3(sv) * random_rotation(rng);
    worst = std::max(worst, max_stiffness_eigenvalue(material, F) / k);
  }
  const double a = 1 + s;
  worst = std::max(worst, max_stiffness_eigenvalue(material, gm::diag3(Vec3{{a, a, a}})) / k);
  std::printf("[ materials ] %s: max eig(dP/dF)/k = %.4f over |sigma-1| <= %.2f\n", what, worst, s);
  EXPECT_LE(worst, 1 + 1e-7) << what;
}
}  // namespace

TEST(Materials, NewLawsStressIsEnergyGradient) {
  expect_pk1_is_energy_gradient(gm::NeoHookean::from_young_poisson(1e6, 0.3), "neo_hookean");
  expect_pk1_is_energy_gradient(gm::NeoHookean::from_young_poisson(1e6, 0.45),
                                "neo_hookean nu=0.45");
  expect_pk1_is_energy_gradient(gm::StVK::from_young_poisson(1e6, 0.3), "stvk");
  expect_pk1_is_energy_gradient(gm::LinearElastic::from_young_poisson(1e6, 0.3), "linear");
}

TEST(Materials, NewLawsRestRotationAndFrameIndifference) {
  // The stable Neo-Hookean energy subtracts its O(mu) rest value: rounding of that shift.
  expect_rest_and_rotation_free(gm::NeoHookean::from_young_poisson(1e6, 0.3), 1e6, "neo_hookean",
                                1e-12);
  expect_rest_and_rotation_free(gm::StVK::from_young_poisson(1e6, 0.3), 1e6, "stvk");
  expect_frame_indifference(gm::NeoHookean::from_young_poisson(1e6, 0.3), "neo_hookean");
  expect_frame_indifference(gm::StVK::from_young_poisson(1e6, 0.3), "stvk");
  // Linear elasticity is stress free at rest but, by construction, not under rotation.
  const auto lin = gm::LinearElastic::from_young_poisson(1e6, 0.3);
  EXPECT_EQ(lin.energy(gm::identity3()), 0.0);
  std::mt19937_64 rng(17);
  EXPECT_GT(lin.energy(random_rotation(rng)), 1.0);
}

TEST(Materials, EveryLawIsLinearElasticityAtRest) {
  for (double nu : {0.0, 0.3, 0.45}) {
    expect_linear_elasticity_at_rest<gm::FixedCorotated>(1e6, nu, "corotated");
    expect_linear_elasticity_at_rest<gm::NeoHookean>(1e6, nu, "neo_hookean");
    expect_linear_elasticity_at_rest<gm::StVK>(1e6, nu, "stvk");
    expect_linear_elasticity_at_rest<gm::LinearElastic>(1e6, nu, "linear");
  }
}

TEST(Materials, NeoHookeanIsFiniteAndRestoringWhenInverted) {
  const auto nh = gm::NeoHookean::from_young_poisson(1e6, 0.3);
  for (const Mat3& F : {gm::diag3(Vec3{{1, 1, 0}}), gm::diag3(Vec3{{1, 1, -0.5}}),
                        Mat3{{0, 0, 0, 0, 0, 0, 0, 0, 0}}}) {
    const Mat3 P = nh.pk1(F);
    EXPECT_TRUE(std::isfinite(nh.energy(F)));
    for (double x : P.a) EXPECT_TRUE(std::isfinite(x));
  }
  // Flattened along z: the stress pushes the element back out (P_zz < 0 means dpsi/dF_zz < 0).
  EXPECT_LT(nh.pk1(gm::diag3(Vec3{{1, 1, 0}}))(2, 2), 0.0);
  EXPECT_GT(nh.energy(gm::diag3(Vec3{{1, 1, -0.5}})), nh.energy(gm::diag3(Vec3{{1, 1, 0.5}})));
}

// F = R1 diag(s) R2 with random rotations: a deformation with the given principal stretches.
Mat3 with_stretches(std::mt19937_64& rng, const Vec3& s) {
  return random_rotation(rng) * gm::diag3(s) * random_rotation(rng);
}

TEST(Materials, StVKStretchScreenAgreesWithTheSvd) {
  // stretches_above (no SVD) must say whether det F > 0 and every principal stretch exceeds sc,
  // as the signed SVD says, except within rounding of the threshold.
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> stretch(0.3, 1.6), sign(-1, 1);
  const double sc = 0.6;
  int above = 0, below = 0;
  for (int i = 0; i < 20000; ++i) {
    Vec3 s{{stretch(rng), stretch(rng), stretch(rng)}};
    if (i % 7 == 0) s[i % 3] = sign(rng);  // some flattened or inverted
    const Mat3 F = with_stretches(rng, s);
    Mat3 U, V;
    Vec3 sg;
    gm::svd3(F, U, sg, V);
    if (std::abs(sg[2] - sc) < 1e-9) continue;
    const bool svd_says = sg[2] > sc;
    EXPECT_EQ(gm::StVK::stretches_above(F.a, sc), svd_says)
        << "sigma " << sg[0] << " " << sg[1] << " " << sg[2];
    (svd_says ? above : below)++;
  }
  EXPECT_GT(above, 4000);
  EXPECT_GT(below, 4000);
}

TEST(Materials, StVKContinuationIsStVKAboveTheStretchAndC1AcrossIt) {
  const auto law = gm::StVK::from_young_poisson(1e6, 0.3);
  const double sc = 0.6;
  std::mt19937_64 rng(29);
  Mat3 P;
  // At and above sc: untouched.
  for (int i = 0; i < 100; ++i) {
    const Mat3 F = with_stretches(rng, Vec3{{1.2, 0.9, 0.61}});
    EXPECT_FALSE(law.pk1_continued(F, sc, P));
  }
  // Across sc, along one stretch with the others fixed: the stress and its slope are continuous
  // (the first-order expansion about sc), and below sc the slope stays StVK's at sc.
  const Mat3 R1 = random_rotation(rng), R2 = random_rotation(rng);
  auto stress = [&](double s) {
    const Mat3 F = R1 * gm::diag3(Vec3{{1.1, 0.95, s}}) * R2;
    Mat3 Pc = law.pk1(F);
    law.pk1_continued(F, sc, Pc);
    return Pc;
  };
  const double d = 1e-5;
  const Mat3 lo = stress(sc - d), mid = stress(sc), hi = stress(sc + d);
  double scale = 0, jump1 = 0;
  for (int i = 0; i < 9; ++i) {
    scale = std::max(scale, std::abs(mid.a[i]));
    // second difference: O(d^2 P'') for a C1 function, O(d P') across a kink
    jump1 = std::max(jump1, std::abs(hi.a[i] - 2 * mid.a[i] + lo.a[i]));
  }
  EXPECT_LT(jump1, 1e-6 * scale);
  const Mat3 a = stress(0.3), b = stress(0.0), c = stress(-0.3);
  for (int i = 0; i < 9; ++i)  // linear below sc: equal differences
    EXPECT_NEAR(a.a[i] - b.a[i], b.a[i] - c.a[i], 1e-9 * scale) << i;
}

TEST(Materials, StVKContinuationPushesAnInvertedPointBack) {
  // StVK's energy depends on C = F^T F only, so a reflection (C = I, det F = -1) is stress free:
  // a Gauss point can sit inverted at zero energy. Continued, the stress opposes the inversion.
  const auto law = gm::StVK::from_young_poisson(1e6, 0.3);
  std::mt19937_64 rng(31);
  const Mat3 mirror = random_rotation(rng) * gm::diag3(Vec3{{1, 1, -1}}) * random_rotation(rng);
  for (double x : law.pk1(mirror).a) EXPECT_NEAR(x, 0.0, 1e-9);
  Mat3 P;
  ASSERT_TRUE(law.pk1_continued(mirror, 0.6, P));
  double norm = 0;
  for (double x : P.a) norm += x * x;
  EXPECT_GT(std::sqrt(norm), 1e5);
  // The principal stress along the smallest stretch at sc (the others 1.1 and 0.95): below it the
  // continued stress is more compressive still, so dpsi = P : dF < 0 for dF growing that
  // stretch back (dF = R1 diag(0, 0, 1) R2).
  const double sum = (1.21 - 1) + (0.9025 - 1) + (0.36 - 1);
  const double at_sc = 0.6 * (law.mu * (0.36 - 1) + 0.5 * law.lambda * sum);
  ASSERT_LT(at_sc, 0);
  for (double s : {-0.8, -0.5, 0.0, 0.3}) {
    const Mat3 R1 = random_rotation(rng), R2 = random_rotation(rng);
    const Mat3 F = R1 * gm::diag3(Vec3{{1.1, 0.95, s}}) * R2;
    P = law.pk1(F);
    ASSERT_TRUE(law.pk1_continued(F, 0.6, P)) << s;
    const Mat3 dF = R1 * gm::diag3(Vec3{{0, 0, 1}}) * R2;
    double work = 0;
    for (int i = 0; i < 9; ++i) work += P.a[i] * dF.a[i];
    EXPECT_LT(work, at_sc) << s;
  }
}

TEST(Materials, NewLawsProjectionStiffnessBoundsTheStressJacobian) {
  for (double nu : {0.0, 0.3, 0.45}) {
    expect_projection_stiffness_bounds(gm::NeoHookean::from_young_poisson(1e6, nu), 0.1,
                                       "neo_hookean");
    expect_projection_stiffness_bounds(gm::StVK::from_young_poisson(1e6, nu), 0.1, "stvk");
    expect_projection_stiffness_bounds(gm::LinearElastic::from_young_poisson(1e6, nu), 0.1,
                                       "linear");
  }
}

TEST(MaterialRegistry, AllLawsRegistered) {
  const auto names = gm::known_materials();
  for (const char* n : {"arap", "corotated", "linear", "neo_hookean", "stvk"})
    EXPECT_NE(std::find(names.begin(), names.end(), n), names.end()) << n;
}
