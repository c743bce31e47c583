// BlockLDLT (the voxel FE forward model's linear solver) against Eigen's SimplicialLDLT on
// block-structured SPD matrices like the model's step matrices: a grid of nodes with 3 dofs,
// coupled to their neighbours by dense 3x3 blocks, plus isolated entries and an empty row pattern.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

#include "forward/BlockLDLT.hpp"
#include "forward/NodeBlockProduct.hpp"

namespace gen4d::forward {
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

// Every instruction set's build of the block kernels gives the same bits: each vector lane
// does the scalar block product's arithmetic in its order (no fused multiply-add).
TEST(BlockLDLT, EveryInstructionSetGivesTheSameBits) {
  const std::string best = BlockLDLT::isa();
  const auto isas = BlockLDLT::isas();
  ASSERT_FALSE(isas.empty());
  EXPECT_EQ(isas.front(), "baseline");
  for (auto [nx, ny, nz] : {std::array<int, 3>{2, 2, 2}, {7, 3, 4}, {21, 5, 5}}) {
    const SpMat A = grid_matrix(nx, ny, nz, 11u + static_cast<unsigned>(nz));
    std::mt19937 rng(5);
    std::normal_distribution<double> g;
    Eigen::VectorXd b(A.rows());
    for (Eigen::Index i = 0; i < b.size(); ++i) b[i] = g(rng);
    Eigen::VectorXd x0;
    for (const std::string& isa : isas) {
      BlockLDLT::set_isa(isa);
      BlockLDLT blk;
      blk.analyze(A);
      ASSERT_TRUE(blk.factorize(A)) << isa;
      Eigen::VectorXd x;
      blk.solve(b, x);
      EXPECT_LT((A * x - b).norm(), 1e-12 * b.norm()) << isa;
      if (x0.size() == 0) x0 = x;
      for (Eigen::Index i = 0; i < x.size(); ++i)
        ASSERT_EQ(x[i], x0[i]) << isa << " " << nx << "x" << ny << "x" << nz << " entry " << i;
    }
  }
  BlockLDLT::set_isa(best);
  EXPECT_EQ(BlockLDLT::isa(), best);
  EXPECT_THROW(BlockLDLT::set_isa("sse9"), std::invalid_argument);
}

TEST(BlockLDLT, FactorsAnIndefiniteMatrixAndReportsASingularOne) {
  // Indefinite but with nonsingular leading block minors: factors and solves.
  SpMat A = grid_matrix(4, 3, 2, 5u);
  for (int i = 0; i < 6; ++i) A.coeffRef(i, i) = -A.coeff(i, i);
  BlockLDLT blk;
  blk.analyze(A);
  ASSERT_TRUE(blk.factorize(A));
  Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(A.rows(), -1.0, 2.0), x;
  blk.solve(b, x);
  EXPECT_LT((A * x - b).norm(), 1e-12 * b.norm());
  // [[B, B], [B, B]]: the second pivot B - B B^-1 B is zero.
  std::vector<Eigen::Triplet<double>> t;
  for (int I = 0; I < 2; ++I)
    for (int J = 0; J < 2; ++J)
      for (int a = 0; a < 3; ++a)
        for (int c = 0; c < 3; ++c) t.emplace_back(3 * I + a, 3 * J + c, a == c ? 2.0 : 0.5);
  SpMat S(6, 6);
  S.setFromTriplets(t.begin(), t.end());
  blk.analyze(S);
  EXPECT_FALSE(blk.factorize(S));
  SpMat Z(3, 3);  // all zero
  Z.insert(0, 0) = 0.0;
  blk.analyze(Z);
  EXPECT_FALSE(blk.factorize(Z));
}

TEST(BlockLDLT, FactorsASubsetOfTheAnalysedPatternAndRejectsMore) {
  const SpMat A = grid_matrix(5, 4, 3, 9u);
  SpMat diag(A.rows(), A.cols());  // the diagonal blocks alone
  std::vector<Eigen::Triplet<double>> t;
  for (int k = 0; k < A.outerSize(); ++k)
    for (SpMat::InnerIterator it(A, k); it; ++it)
      if (it.row() / 3 == it.col() / 3) t.emplace_back(it.row(), it.col(), it.value());
  diag.setFromTriplets(t.begin(), t.end());
  BlockLDLT blk;
  blk.analyze(A);
  ASSERT_TRUE(blk.factorize(diag));
  Eigen::VectorXd b = Eigen::VectorXd::Ones(A.rows()), x;
  blk.solve(b, x);
  EXPECT_LT((diag * x - b).norm(), 1e-12 * b.norm());
  blk.analyze(diag);
  EXPECT_THROW(blk.factorize(A), std::logic_error);
}

TEST(BlockLDLT, RejectsAMatrixWithoutNodeBlocks) {
  BlockLDLT blk;
  EXPECT_THROW(blk.analyze(SpMat(4, 4)), std::logic_error);
}

TEST(NodeBlockProduct, IsEigensSparseProductBitForBitAndRefusesOtherPatterns) {
  // A mass-like matrix m (x) I3 on a 6x3x3 node grid (a node with its 26 neighbours), random
  // values of mixed magnitude, entries summed from duplicates as the model assembles them.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  const int nx = 6, ny = 3, nz = 3, n = nx * ny * nz;
  auto id = [&](int i, int j, int k) { return (k * ny + j) * nx + i; };
  std::vector<Eigen::Triplet<double>> t;
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        for (int dk = -1; dk <= 1; ++dk)
          for (int dj = -1; dj <= 1; ++dj)
            for (int di = -1; di <= 1; ++di) {
              const int i2 = i + di, j2 = j + dj, k2 = k + dk;
              if (i2 < 0 || i2 >= nx || j2 < 0 || j2 >= ny || k2 < 0 || k2 >= nz) continue;
              const double v = std::exp(6 * u(rng) - 3), w = 0.1 * u(rng);
              for (int a = 0; a < 3; ++a) {
                t.emplace_back(3 * id(i, j, k) + a, 3 * id(i2, j2, k2) + a, v);
                t.emplace_back(3 * id(i, j, k) + a, 3 * id(i2, j2, k2) + a, w);
              }
            }
  SpMat M(3 * n, 3 * n);
  M.setFromTriplets(t.begin(), t.end());
  const NodeBlockProduct P(M);
  ASSERT_TRUE(P.ok());
  Eigen::VectorXd x(3 * n), y(3 * n);
  for (int i = 0; i < 3 * n; ++i) x[i] = std::exp(8 * u(rng) - 4) * (u(rng) < 0.5 ? -1 : 1);
  P.apply(x, y);
  Eigen::VectorXd ref(3 * n);
  ref.noalias() = M * x;
  for (int i = 0; i < 3 * n; ++i) ASSERT_EQ(y[i], ref[i]) << i;
  // Not of the form: an entry across axes, or axes with different values.
  SpMat across = M;
  across.coeffRef(0, 4) = 1.0;
  EXPECT_FALSE(NodeBlockProduct(across).ok());
  SpMat uneven = M;
  uneven.coeffRef(1, 1) *= 2;
  EXPECT_FALSE(NodeBlockProduct(uneven).ok());
  EXPECT_FALSE(NodeBlockProduct(grid_matrix(3, 2, 2, 1)).ok());  // dense 3x3 blocks
}

}  // namespace
}  // namespace gen4d::forward
