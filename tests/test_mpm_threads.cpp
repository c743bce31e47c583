// MPM's host kernels on several threads: P2G's slab colouring, the threaded grid update, G2P,
// guard and material blocks give the same bits as one thread, at every rank count.
#include <gtest/gtest.h>
#include <mpi.h>
#include <omp.h>

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "materials/Svd3.hpp"
#include "mpm_test_util.hpp"
#include "mpm_threads_scene.hpp"

namespace gen4d {
namespace {

std::vector<double> run_with_threads(const std::string& model, int threads, int substeps) {
  const int before = omp_get_max_threads();
  omp_set_num_threads(threads);
  auto solver = test::kernel_scene(MPI_COMM_WORLD, model, false);
  double t = 0;
  test::run(*solver, substeps, t);
  omp_set_num_threads(before);
  return test::gather_sorted(MPI_COMM_WORLD, solver->particles());
}

class MpmThreads : public ::testing::TestWithParam<const char*> {};

TEST_P(MpmThreads, AnyThreadCountGivesTheSameBits) {
  const auto one = run_with_threads(GetParam(), 1, 30);
  for (int threads : {2, 3}) {
    const auto many = run_with_threads(GetParam(), threads, 30);
    ASSERT_EQ(one.size(), many.size());
    long differ = 0;
    const int R = mpm::Particles::kRecord;
    for (std::size_t i = 0; i < one.size(); ++i)
      differ += std::memcmp(&one[i], &many[i], sizeof(double)) != 0;
    EXPECT_EQ(differ, 0) << threads << " threads";
    int rank = 0;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    if (rank == 0) EXPECT_GT(one.size(), 8000u * R);  // above the serial threshold per rank
  }
}

INSTANTIATE_TEST_SUITE_P(Models, MpmThreads,
                         ::testing::Values("fixed_corotated", "drucker_prager"));

// svd3_batch's vector lanes compute what svd3 computes, bit for bit, for any batch length and
// position in the batch, on rotations, stretches, inversions, rank-deficient and tiny matrices.
TEST(Svd3Batch, EqualsTheScalarSvdBitForBit) {
  std::mt19937 gen(7);
  std::normal_distribution<double> normal(0, 1);
  for (std::size_t n : {1u, 3u, 4u, 5u, 64u, 333u}) {
    std::vector<double> F(9 * n), U(9 * n), S(3 * n), V(9 * n);
    for (std::size_t i = 0; i < n; ++i) {
      for (int k = 0; k < 9; ++k) F[9 * i + k] = (k % 4 == 0 ? 1.0 : 0.0) + 0.3 * normal(gen);
      if (i % 5 == 1)
        for (int k = 0; k < 3; ++k) F[9 * i + 6 + k] *= -1;  // inverted
      if (i % 5 == 2)
        for (int k = 0; k < 3; ++k) F[9 * i + 3 + k] = 2 * F[9 * i + k];  // rank 2
      if (i % 5 == 3)
        for (int k = 0; k < 9; ++k) F[9 * i + k] *= 1e-200;  // tiny
    }
    for (int isa = 0; isa <= static_cast<int>(materials::svd3_batch_best_isa()); ++isa) {
      materials::svd3_batch(n, F.data(), U.data(), S.data(), V.data(),
                            static_cast<materials::SvdIsa>(isa));
      for (std::size_t i = 0; i < n; ++i) {
        materials::Mat3 f, u, v;
        materials::Vec3 s;
        std::memcpy(f.a, &F[9 * i], sizeof f.a);
        materials::svd3(f, u, s, v);
        EXPECT_EQ(std::memcmp(u.a, &U[9 * i], sizeof u.a), 0)
            << "isa " << isa << " n " << n << " i " << i;
        EXPECT_EQ(std::memcmp(v.a, &V[9 * i], sizeof v.a), 0)
            << "isa " << isa << " n " << n << " i " << i;
        EXPECT_EQ(std::memcmp(s.v, &S[3 * i], sizeof s.v), 0)
            << "isa " << isa << " n " << n << " i " << i;
      }
    }
  }
}

}  // namespace
}  // namespace gen4d
