// Halo exchange and fused reductions give the same answer at 1, 2 and 4 ranks.
#include <gtest/gtest.h>
#include <mpi.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "parallel/Grid.hpp"
#include "parallel/Halo.hpp"
#include "parallel/Reduce.hpp"

using namespace gen4d::parallel;

namespace {
double field_value(long i, long j, long k, int c) {
  return std::sin(0.3 * i + 1.7 * c) + 0.01 * j * j - 0.5 * k + 1000.0 * c;
}
}  // namespace

TEST(Halo, GatherFillsGhostsFromOwners) {
  NodeGrid grid(MPI_COMM_WORLD, {9, 7, 6});
  Halo halo(grid, 3);
  const Box& g = grid.ghosted_nodes();
  const Box& o = grid.owned_nodes();
  std::vector<double> f(3 * g.size(), -1.0);
  for (long k = o.start[2]; k < o.start[2] + o.count[2]; ++k)
    for (long j = o.start[1]; j < o.start[1] + o.count[1]; ++j)
      for (long i = o.start[0]; i < o.start[0] + o.count[0]; ++i)
        for (int c = 0; c < 3; ++c) f[3 * g.index(i, j, k) + c] = field_value(i, j, k, c);
  halo.gather(f.data());
  for (long k = g.start[2]; k < g.start[2] + g.count[2]; ++k)
    for (long j = g.start[1]; j < g.start[1] + g.count[1]; ++j)
      for (long i = g.start[0]; i < g.start[0] + g.count[0]; ++i)
        for (int c = 0; c < 3; ++c)
          ASSERT_EQ(f[3 * g.index(i, j, k) + c], field_value(i, j, k, c)) << i << j << k;
}

TEST(Halo, ScatterAddSumsGhostContributions) {
  // Every rank adds 1 to each node of its ghosted box: a node's total is the number of
  // ranks whose ghosted box holds it, which we compute independently by allgathering boxes.
  NodeGrid grid(MPI_COMM_WORLD, {8, 6, 5});
  Halo halo(grid, 1);
  const Box& g = grid.ghosted_nodes();
  std::vector<double> f(g.size(), 1.0);
  halo.scatter_add(f.data());
  std::vector<long> boxes(6 * grid.size());
  long mine[6] = {g.start[0], g.start[1], g.start[2], g.count[0], g.count[1], g.count[2]};
  MPI_Allgather(mine, 6, MPI_LONG, boxes.data(), 6, MPI_LONG, MPI_COMM_WORLD);
  for (long k = g.start[2]; k < g.start[2] + g.count[2]; ++k)
    for (long j = g.start[1]; j < g.start[1] + g.count[1]; ++j)
      for (long i = g.start[0]; i < g.start[0] + g.count[0]; ++i) {
        int expected = 0;
        for (int r = 0; r < grid.size(); ++r) {
          Box b{{boxes[6 * r], boxes[6 * r + 1], boxes[6 * r + 2]},
                {boxes[6 * r + 3], boxes[6 * r + 4], boxes[6 * r + 5]}};
          expected += b.contains(i, j, k) ? 1 : 0;
        }
        ASSERT_EQ(f[g.index(i, j, k)], expected);
      }
  if (grid.size() > 1) {
    // Some node must be shared, otherwise the test would not exercise communication.
    long shared = 0;
    for (double v : f) shared += v > 1.0;
    long total = 0;
    MPI_Allreduce(&shared, &total, 1, MPI_LONG, MPI_SUM, MPI_COMM_WORLD);
    EXPECT_GT(total, 0);
  }
}

TEST(Grid, OwnedBoxesTileTheGridAndAdjacentCellsCoverOwnedNodes) {
  NodeGrid grid(MPI_COMM_WORLD, {10, 5, 4});
  long n = grid.owned_nodes().size(), total = 0;
  MPI_Allreduce(&n, &total, 1, MPI_LONG, MPI_SUM, MPI_COMM_WORLD);
  EXPECT_EQ(total, 10 * 5 * 4);
  long c = grid.owned_cells().size(), ctotal = 0;
  MPI_Allreduce(&c, &ctotal, 1, MPI_LONG, MPI_SUM, MPI_COMM_WORLD);
  EXPECT_EQ(ctotal, 9 * 4 * 3);
  const Box& cells = grid.adjacent_cells();
  const Box& g = grid.ghosted_nodes();
  for (int d = 0; d < 3; ++d) {
    EXPECT_GE(cells.start[d], g.start[d]);
    EXPECT_LE(cells.start[d] + cells.count[d] + 1, g.start[d] + g.count[d]);
  }
}

TEST(Reduce, FusedSumsAreIndependentOfDecomposition) {
  // 1e5 terms of wildly different magnitudes, split by rank; the result must equal the
  // same exact sum computed on one rank, to the last bit.
  const int n_terms = 100000, n_sums = 5;
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<double> terms(n_terms * n_sums);
  for (auto& t : terms) t = u(rng) * std::pow(10.0, 8 * u(rng));
  int rank, size;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  std::vector<ExactSum> local(n_sums), serial(n_sums);
  for (int s = 0; s < n_sums; ++s)
    for (int i = 0; i < n_terms; ++i) {
      serial[s].add(terms[s * n_terms + i]);
      // Reverse order on odd ranks to show order independence as well.
      const int ii = (rank % 2) ? n_terms - 1 - i : i;
      if (ii % size == rank) local[s].add(terms[s * n_terms + ii]);
    }
  Reducer red(MPI_COMM_WORLD);
  std::vector<double> global(n_sums);
  red.sum(local.data(), global.data(), n_sums);
  for (int s = 0; s < n_sums; ++s) EXPECT_EQ(global[s], serial[s].value()) << s;
}

TEST(Reduce, ExactSumIsExactAndRoundedOnce) {
  // Cancellation: the exact answer survives, whatever the order or split.
  ExactSum a;
  for (double v : {1e300, 3.0, -1e300, 1e-300, -3.0}) a.add(v);
  EXPECT_EQ(a.value(), 1e-300);
  // Rounding happens once, to nearest, ties to even.
  ExactSum tie, above;
  for (double v : {1.0, std::ldexp(1.0, -53)}) tie.add(v);
  EXPECT_EQ(tie.value(), 1.0);
  for (double v : {1.0, std::ldexp(1.0, -53), std::ldexp(1.0, -160)}) above.add(v);
  EXPECT_EQ(above.value(), 1.0 + std::ldexp(1.0, -52));
  // Negative sums, subnormals and the extremes of the range.
  ExactSum neg;
  for (double v : {-2.5, std::numeric_limits<double>::denorm_min(), 1.0}) neg.add(v);
  EXPECT_EQ(neg.value(), -1.5);
  ExactSum tiny;
  for (int i = 0; i < 3; ++i) tiny.add(std::numeric_limits<double>::denorm_min());
  EXPECT_EQ(tiny.value(), 3 * std::numeric_limits<double>::denorm_min());
  ExactSum big;
  big.add(std::numeric_limits<double>::max());
  big.add(-std::numeric_limits<double>::max());
  big.add(-0.25);
  EXPECT_EQ(big.value(), -0.25);
  // Non-finite terms propagate.
  ExactSum inf;
  inf.add(1.0);
  inf.add(std::numeric_limits<double>::infinity());
  EXPECT_EQ(inf.value(), std::numeric_limits<double>::infinity());
  ExactSum nan;
  nan.add(std::numeric_limits<double>::quiet_NaN());
  EXPECT_TRUE(std::isnan(nan.value()));
}

TEST(Reduce, NearCancellingSumsAreIndependentOfDecomposition) {
  // Pairs +x, -x of random magnitude plus a few tiny terms, each pair split across ranks:
  // the global sum must be exactly the tiny terms' sum at any rank count.
  int rank, size;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  ExactSum local, tiny;
  for (int i = 0; i < 20000; ++i) {
    const double x = u(rng) * std::pow(10.0, 12 * u(rng));
    if (i % size == rank) local.add(x);
    if ((i + 1) % size == rank) local.add(-x);
    if (i % 1000 == 0) {
      const double t = 1e-20 * u(rng);
      tiny.add(t);
      if (i % size == rank) local.add(t);
    }
  }
  Reducer red(MPI_COMM_WORLD);
  double global = 0;
  red.sum(&local, &global, 1);
  EXPECT_EQ(global, tiny.value());
  EXPECT_NE(global, 0.0);
}
