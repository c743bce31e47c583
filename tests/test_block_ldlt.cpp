// BlockLDLT (the diagnose forward model's linear solver) against Eigen's SimplicialLDLT on
// block-structured SPD matrices like the model's step matrices: a grid of nodes with 3 dofs,
// coupled to their neighbours by dense 3x3 blocks, plus isolated entries and an empty row pattern.
#include <gtest/gtest.h>

#include <random>

#include "diagnose/BlockLDLT.hpp"

namespace gen4d::diagnose {
namespace {

using SpMat = Eigen::SparseMatrix<double>;

//! Nodes of an nx x ny x nz grid, each coupled to the 26 around it (hexahedral stencil),
//! made SPD by a dominant diagonal.
SpMat grid_matrix(int nx, int ny, int nz, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  const int n = nx * ny * nz;
  auto id = [&](int i, int j, int k) { return (k * ny + j) * nx + i; };
  std::vector<Eigen::Triplet<double>> t;
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        for (int dk = 0; dk <= 1; ++dk)
          for (int dj = -1; dj <= 1; ++dj)
            for (int di = -1; di <= 1; ++di) {
              if (dk == 0 && (dj < 0 || (dj == 0 && di <= 0))) continue;  // each pair once
              const int i2 = i + di, j2 = j + dj, k2 = k + dk;
              if (i2 < 0 || i2 >= nx || j2 < 0 || j2 >= ny || k2 >= nz) continue;
              const int p = id(i, j, k), q = id(i2, j2, k2);
              for (int a = 0; a < 3; ++a)
                for (int b = 0; b < 3; ++b) {
                  const double v = 0.3 * u(rng);
                  t.emplace_back(3 * p + a, 3 * q + b, v);
                  t.emplace_back(3 * q + b, 3 * p + a, v);
                }
            }
  for (int p = 0; p < n; ++p)
    for (int a = 0; a < 3; ++a) {
      t.emplace_back(3 * p + a, 3 * p + a, 30.0 + u(rng));
      for (int b = 0; b < a; ++b) {
        const double v = 0.5 * u(rng);
        t.emplace_back(3 * p + a, 3 * p + b, v);
        t.emplace_back(3 * p + b, 3 * p + a, v);
      }
    }
  SpMat A(3 * n, 3 * n);
  A.setFromTriplets(t.begin(), t.end());
  return A;
}

TEST(BlockLDLT, SolvesLikeEigenLDLT) {
  for (auto [nx, ny, nz] : {std::array<int, 3>{1, 1, 1}, {4, 3, 2}, {21, 5, 5}}) {
    const SpMat A = grid_matrix(nx, ny, nz, 7u + static_cast<unsigned>(nx));
    BlockLDLT blk;
    blk.analyze(A);
    ASSERT_TRUE(blk.factorize(A));
    Eigen::SimplicialLDLT<SpMat> ref(A);
    ASSERT_EQ(ref.info(), Eigen::Success);
    std::mt19937 rng(3);
    std::normal_distribution<double> g;
    Eigen::VectorXd b(A.rows()), x;
    for (Eigen::Index i = 0; i < b.size(); ++i) b[i] = g(rng);
    blk.solve(b, x);
    const Eigen::VectorXd xr = ref.solve(b);
    EXPECT_LT((x - xr).norm(), 1e-12 * xr.norm()) << nx << "x" << ny << "x" << nz;
    EXPECT_LT((A * x - b).norm(), 1e-12 * b.norm());
    // Refactorizing new values on the same pattern (the model's tangent refresh).
    const SpMat A2 = 2.0 * A;
    ASSERT_TRUE(blk.factorize(A2));
    blk.solve(b, x);
    EXPECT_LT((x - 0.5 * xr).norm(), 1e-12 * xr.norm());
  }
}

TEST(BlockLDLT, ReportsAnIndefiniteSingularMatrix) {
  SpMat A(3, 3);  // all zero: LDL^T has a zero pivot
  A.insert(0, 0) = 0.0;
  BlockLDLT blk;
  blk.analyze(A);
  EXPECT_FALSE(blk.factorize(A));
}

TEST(BlockLDLT, RejectsAMatrixWithoutNodeBlocks) {
  BlockLDLT blk;
  EXPECT_THROW(blk.analyze(SpMat(4, 4)), std::logic_error);
}

}  // namespace
}  // namespace gen4d::diagnose
