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
#include "mpm/HostKernels.hpp"
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

// P2G and G2P's AVX2 copies (a node's four values in one instruction) give the baseline copies'
// bits, on particles scattered anywhere in a small grid with random velocities, affine
// matrices, stresses and grid velocities.
TEST(MpmHostKernels, EveryInstructionSetGivesTheSameBits) {
  std::mt19937 gen(11);
  std::uniform_real_distribution<double> pos(0.15, 0.85), unit(-1, 1);
  const long nodes = 12, n = 500;
  std::vector<double> x(3 * n), v(3 * n), C(9 * n), tau(9 * n), mass(n), vol0(n), F(9 * n);
  std::vector<std::uint8_t> flag(n, 0);
  for (long i = 0; i < n; ++i) {
    for (int d = 0; d < 3; ++d) x[3 * i + d] = pos(gen), v[3 * i + d] = unit(gen);
    for (int k = 0; k < 9; ++k) C[9 * i + k] = 3 * unit(gen), tau[9 * i + k] = 1e4 * unit(gen);
    for (int k = 0; k < 9; ++k) F[9 * i + k] = (k % 4 == 0) + 0.1 * unit(gen);
    mass[i] = 1e-3 * (1.5 + unit(gen));
    vol0[i] = 1e-6;
  }
  flag[7] = 1;  // frozen: skipped
  mpm::kernels::P2GArgs a{};
  a.x = x.data(), a.v = v.data(), a.C = C.data(), a.tau = tau.data();
  a.mass = mass.data(), a.vol0 = vol0.data(), a.flag = flag.data();
  a.dx = 1.0 / (nodes - 1);
  a.stress_scale = -1e-4 * 4 / (a.dx * a.dx);
  a.rpic = 0.1;
  a.inv_qm = std::ldexp(1.0, 40);
  a.inv_qp = std::ldexp(1.0, 36);
  a.gx = a.gy = nodes;
  mpm::kernels::G2PArgs b{};
  b.x = x.data(), b.v = v.data(), b.C = C.data(), b.F = F.data(), b.flag = flag.data();
  b.dx = a.dx;
  b.dt = 1e-4;
  b.gx = b.gy = nodes;
  b.advance = true;
  std::vector<double> vel(3 * nodes * nodes * nodes + 1);
  for (auto& w : vel) w = unit(gen);
  b.vel = vel.data();
  std::vector<std::vector<double>> grids, states;
  for (int isa = 0; isa <= static_cast<int>(mpm::host::best_isa()); ++isa) {
    const auto x0 = x, v0 = v, C0 = C, F0 = F;
    std::vector<double> grid(4 * nodes * nodes * nodes, 0.0);
    mpm::host::p2g(a, nullptr, 0, n, grid.data(), static_cast<mpm::host::Isa>(isa));
    mpm::host::g2p(b, 0, n, nullptr, nullptr, static_cast<mpm::host::Isa>(isa));
    grids.push_back(grid);
    std::vector<double> state = x;
    for (const auto* arr : {&v, &C, &F}) state.insert(state.end(), arr->begin(), arr->end());
    states.push_back(state);
    x = x0, v = v0, C = C0, F = F0;
  }
  double mass_sum = 0;
  for (long k = 0; k < nodes * nodes * nodes; ++k) mass_sum += grids[0][4 * k];
  EXPECT_GT(mass_sum, 0.0);  // the particles did scatter
  for (std::size_t isa = 1; isa < grids.size(); ++isa) {
    EXPECT_EQ(std::memcmp(grids[0].data(), grids[isa].data(), grids[0].size() * sizeof(double)), 0)
        << "P2G, isa " << isa;
    EXPECT_EQ(std::memcmp(states[0].data(), states[isa].data(), states[0].size() * sizeof(double)),
              0)
        << "G2P, isa " << isa;
  }
  if (grids.size() == 1) GTEST_LOG_(INFO) << "this CPU has no AVX2: only the baseline copy ran";
}

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
