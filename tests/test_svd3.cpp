// Signed 3x3 SVD: accuracy, conventions and edge cases against Eigen's JacobiSVD.
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "materials/Svd3.hpp"
#include "mat3_test_util.hpp"

namespace gm = gen4d::materials;
using gen4d::test::from_eigen;
using gen4d::test::to_eigen;
using gm::Mat3;
using gm::Vec3;

namespace {

Mat3 random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> normal;
  Eigen::Quaterniond q(normal(rng), normal(rng), normal(rng), normal(rng));
  return from_eigen(q.normalized().toRotationMatrix());
}

Mat3 random_uniform(std::mt19937_64& rng, double scale) {
  std::uniform_real_distribution<double> uniform(-scale, scale);
  Mat3 F;
  for (double& x : F.a) x = uniform(rng);
  return F;
}

// Worst errors over a set of decompositions; each is relative to ||F|| (or to sigma_max).
struct SvdErrors {
  double reconstruction = 0;  // ||U S V^T - F|| / ||F||
  double orthogonality = 0;   // max(||U^T U - I||, ||V^T V - I||)
  double determinant = 0;     // max(|det U - 1|, |det V - 1|)
  double versus_eigen = 0;    // max_i ||sigma_i| - sigma_i(Eigen)| / sigma_max(Eigen)
  int order_violations = 0;   // |sigma| not descending, or a negative sigma_0 / sigma_1
  int sign_violations = 0;    // sign of sigma_2 disagrees with the sign of det F

  void add(const Mat3& F) {
    Mat3 U, V;
    Vec3 s;
    gm::svd3(F, U, s, V);
    const double normF = gm::frobenius_norm(F);
    const double denom = normF > 0 ? normF : 1.0;
    const Mat3 back = gm::compose_svd(U, s, V);
    reconstruction = std::max(reconstruction, gm::frobenius_norm(back - F) / denom);
    const Mat3 I = gm::identity3();
    orthogonality = std::max({orthogonality, gm::frobenius_norm(gm::transpose(U) * U - I),
                              gm::frobenius_norm(gm::transpose(V) * V - I)});
    determinant = std::max({determinant, std::abs(gm::det(U) - 1), std::abs(gm::det(V) - 1)});
    if (!(std::abs(s[0]) >= std::abs(s[1]) && std::abs(s[1]) >= std::abs(s[2]) && s[0] >= 0 &&
          s[1] >= 0))
      ++order_violations;
    // det F = s0 s1 s2; where it is clearly nonzero the sign must sit in sigma_2.
    const double detF = gm::det(F);
    const double det_scale = normF * normF * normF;
    if (std::abs(detF) > 1e-10 * det_scale && (detF < 0) != (s[2] < 0)) ++sign_violations;
    Eigen::JacobiSVD<Eigen::Matrix3d> reference(to_eigen(F));
    const Eigen::Vector3d ref = reference.singularValues();
    const double ref_max = ref[0] > 0 ? ref[0] : 1.0;
    for (int i = 0; i < 3; ++i)
      versus_eigen = std::max(versus_eigen, std::abs(std::abs(s[i]) - ref[i]) / ref_max);
  }

  void expect_accurate(const char* what) const {
    std::printf("[ svd3 ] %-28s recon %.2e  orth %.2e  det %.2e  vs Eigen %.2e\n", what,
                reconstruction, orthogonality, determinant, versus_eigen);
    EXPECT_LT(reconstruction, 1e-12) << what;
    EXPECT_LT(orthogonality, 1e-12) << what;
    EXPECT_LT(determinant, 1e-12) << what;
    EXPECT_LT(versus_eigen, 1e-12) << what;
    EXPECT_EQ(order_violations, 0) << what;
    EXPECT_EQ(sign_violations, 0) << what;
  }
};

// R1 diag(sigma) R2 with random rotations: the singular values are known exactly.
Mat3 with_singular_values(std::mt19937_64& rng, const Vec3& sigma) {
  return random_rotation(rng) * gm::diag3(sigma) * random_rotation(rng);
}

}  // namespace

TEST(Svd3, RandomUniformEntries) {
  std::mt19937_64 rng(1);
  SvdErrors errors;
  for (int i = 0; i < 100000; ++i) errors.add(random_uniform(rng, 1.0));
  errors.expect_accurate("uniform [-1,1], 1e5");
}

TEST(Svd3, ScaleInvariance) {
  std::mt19937_64 rng(2);
  SvdErrors small, large;
  for (int i = 0; i < 10000; ++i) {
    small.add(random_uniform(rng, 1e-8));
    large.add(random_uniform(rng, 1e8));
  }
  small.expect_accurate("uniform, scale 1e-8");
  large.expect_accurate("uniform, scale 1e8");
}

TEST(Svd3, RepeatedZeroAndTinySingularValues) {
  std::mt19937_64 rng(3);
  const std::vector<Vec3> spectra = {
      {{1, 1, 1}},       {{2, 2, 1}},         {{2, 1, 1}},  {{1, 1, 0}},
      {{1, 0, 0}},       {{0, 0, 0}},         {{3, 2, 0}},  {{1, 1, 1e-12}},
      {{1, 0.5, 1e-12}}, {{1, 1e-12, 1e-12}}, {{1, 1, -1}}, {{2, 1, -1}},
      {{3, 2, -1e-12}},  {{1, 1e-6, -1e-6}},  {{5, 5, -5}}, {{1 + 1e-9, 1, 1 - 1e-9}},
      {{1e8, 1, 1e-4}}};
  for (const Vec3& sigma : spectra) {
    SvdErrors errors;
    double worst_sigma = 0;  // against the exact singular values, relative to sigma_0
    for (int i = 0; i < 2000; ++i) {
      const Mat3 F = with_singular_values(rng, sigma);
      errors.add(F);
      Mat3 U, V;
      Vec3 s;
      gm::svd3(F, U, s, V);
      const double top = std::abs(sigma[0]) > 0 ? std::abs(sigma[0]) : 1.0;
      for (int k = 0; k < 3; ++k)
        worst_sigma = std::max(worst_sigma, std::abs(s[k] - sigma[k]) / top);
    }
    char label[96];
    std::snprintf(label, sizeof label, "sigma (%.10g, %.10g, %.10g)", sigma[0], sigma[1], sigma[2]);
    errors.expect_accurate(label);
    // The spectra above are sorted and signed as svd3 must return them, so compare signed values.
    EXPECT_LT(worst_sigma, 1e-13) << label;
  }
}

TEST(Svd3, RankOne) {
  std::mt19937_64 rng(4);
  std::normal_distribution<double> normal;
  SvdErrors errors;
  for (int i = 0; i < 20000; ++i) {
    const Eigen::Vector3d u(normal(rng), normal(rng), normal(rng));
    const Eigen::Vector3d v(normal(rng), normal(rng), normal(rng));
    errors.add(from_eigen(u * v.transpose()));
  }
  errors.expect_accurate("rank one u v^T");
}

TEST(Svd3, InvertedPutsTheSignOnTheSmallestValue) {
  std::mt19937_64 rng(5);
  SvdErrors errors;
  for (int i = 0; i < 20000; ++i) {
    Mat3 F = random_uniform(rng, 1.0);
    if (gm::det(F) > 0)
      for (int c = 0; c < 3; ++c) F(0, c) = -F(0, c);
    Mat3 U, V;
    Vec3 s;
    gm::svd3(F, U, s, V);
    ASSERT_LT(s[2], 0.0);
    errors.add(F);
  }
  errors.expect_accurate("det F < 0");
}

TEST(Svd3, ExactDiagonalsAndPermutations) {
  SvdErrors errors;
  const Mat3 diagonals[] = {gm::identity3(),
                            Mat3{{0, 0, 0, 0, 0, 0, 0, 0, 0}},
                            gm::diag3(Vec3{{1, 2, 3}}),
                            gm::diag3(Vec3{{3, 2, 1}}),
                            gm::diag3(Vec3{{-1, 2, 3}}),
                            gm::diag3(Vec3{{-1, -2, 3}}),
                            gm::diag3(Vec3{{-1, -2, -3}}),
                            gm::diag3(Vec3{{0, 5, 0}}),
                            gm::diag3(Vec3{{2, -2, 2}})};
  for (const Mat3& F : diagonals) errors.add(F);
  const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (const auto& p : perms) {
    Mat3 P{{0, 0, 0, 0, 0, 0, 0, 0, 0}};
    for (int r = 0; r < 3; ++r) P(r, p[r]) = 1;
    errors.add(P);
    errors.add(P * gm::diag3(Vec3{{1, 4, 9}}));
    Mat3 U, V;
    Vec3 s;
    gm::svd3(P, U, s, V);
    EXPECT_NEAR(s[0], 1.0, 1e-15);
    EXPECT_NEAR(s[1], 1.0, 1e-15);
    EXPECT_NEAR(s[2], gm::det(P), 1e-15);  // odd permutations are reflections
  }
  errors.expect_accurate("diagonals, permutations");

  Mat3 U, V;
  Vec3 s;
  gm::svd3(gm::diag3(Vec3{{-1, 2, 3}}), U, s, V);
  EXPECT_DOUBLE_EQ(s[0], 3.0);
  EXPECT_DOUBLE_EQ(s[1], 2.0);
  EXPECT_DOUBLE_EQ(s[2], -1.0);
}

TEST(Svd3, PolarRotationIsUVt) {
  std::mt19937_64 rng(6);
  for (int i = 0; i < 1000; ++i) {
    const Mat3 Q = random_rotation(rng);
    const Mat3 S = gm::diag3(Vec3{{2.0, 1.5, 0.5}});
    const Mat3 R = gm::polar_rotation(Q * S);  // F = Q S: rotation times stretch
    EXPECT_LT(gm::frobenius_norm(R - Q), 1e-13);
    // Inverted F: the closest proper rotation, i.e. the rotation of the signed SVD.
    const Mat3 Rinv = gm::polar_rotation(Q * gm::diag3(Vec3{{2.0, 1.5, -0.5}}));
    EXPECT_LT(gm::frobenius_norm(Rinv - Q), 1e-13);
  }
}

TEST(Svd3, FixedSweepCountHasMargin) {
  // One sweep fewer than svd3 uses must already make the columns of F V orthogonal to rounding
  // level (cosine of every pair) on hard cases: clustered, graded and random spectra.
  std::mt19937_64 rng(7);
  const std::vector<Vec3> spectra = {{{1, 1 - 1e-7, 1e-3}}, {{1, 0.999, 0.998}}, {{1e4, 1, 1e-4}},
                                     {{1, 0.5, 0.25}},      {{1, 1, 1e-8}},      {{1e8, 1, 1e-4}}};
  double worst = 0;
  for (int i = 0; i < 20000; ++i) {
    Mat3 B = i % 2 ? random_uniform(rng, 1.0)
                   : with_singular_values(rng, spectra[(i / 2) % spectra.size()]);
    Mat3 V;
    gm::detail::jacobi_orthogonalize(B, V, gm::kSvdJacobiSweeps - 1);
    for (int p = 0; p < 3; ++p)
      for (int q = p + 1; q < 3; ++q) {
        double bpq = 0, bpp = 0, bqq = 0;
        for (int r = 0; r < 3; ++r) {
          bpq += B(r, p) * B(r, q);
          bpp += B(r, p) * B(r, p);
          bqq += B(r, q) * B(r, q);
        }
        worst = std::max(worst, std::abs(bpq) / std::sqrt(bpp * bqq));
      }
  }
  std::printf("[ svd3 ] worst column cosine after %d sweeps: %.2e\n", gm::kSvdJacobiSweeps - 1,
              worst);
  EXPECT_LT(worst, 1e-14);
}

TEST(Svd3, BatchMatchesPointwise) {
  std::mt19937_64 rng(8);
  const std::size_t n = 20000;
  std::vector<double> F(9 * n), U(9 * n), sigma(3 * n), V(9 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const Mat3 f = random_uniform(rng, 2.0);
    std::copy(f.a, f.a + 9, F.begin() + 9 * i);
  }
  gm::svd3_batch(n, F.data(), U.data(), sigma.data(), V.data());
  for (std::size_t i = 0; i < n; ++i) {
    Mat3 f, u, v;
    Vec3 s;
    std::copy(F.begin() + 9 * i, F.begin() + 9 * i + 9, f.a);
    gm::svd3(f, u, s, v);
    for (int k = 0; k < 9; ++k) {
      ASSERT_EQ(U[9 * i + k], u.a[k]);
      ASSERT_EQ(V[9 * i + k], v.a[k]);
    }
    for (int k = 0; k < 3; ++k) ASSERT_EQ(sigma[3 * i + k], s[k]);
  }

  // Informative timing only (shared machine, no assertion).
  const auto start = std::chrono::steady_clock::now();
  const int repeats = 10;
  for (int r = 0; r < repeats; ++r) gm::svd3_batch(n, F.data(), U.data(), sigma.data(), V.data());
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("[ svd3 ] svd3_batch: %.1f ns per 3x3 SVD (%zu matrices x %d, one core)\n",
              1e9 * seconds / (double(n) * repeats), n, repeats);
}
