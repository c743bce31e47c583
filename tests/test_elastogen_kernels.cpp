// ElastoGen's pointwise kernels on the host: the factored Gauss-point gradients and node forces
// against the HexStencil reference, the Newton-polar corotated stress against the SVD path, and
// the threaded sweep and local step, bit-identical at 1, 2 and 3 threads, the sweep equal to
// the per-value kernel the GPU runs.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#if defined(_OPENMP)
#include <omp.h>
#endif

#include "core/ParallelFor.hpp"
#include "elastogen/HexStencil.hpp"
#include "elastogen/LocalKernels.hpp"
#include "elastogen/VoxelSystem.hpp"
#include "elastogen_kernels_scene.hpp"
#include "materials/Arap.hpp"
#include "materials/FixedCorotated.hpp"

using namespace gen4d;
namespace gm = gen4d::materials;

namespace {

void set_threads(int t) {
#if defined(_OPENMP)
  omp_set_num_threads(t);
#else
  (void)t;
#endif
}

double max_abs(const double* a, std::size_t n) {
  double m = 0;
  for (std::size_t i = 0; i < n; ++i) m = std::max(m, std::fabs(a[i]));
  return m;
}

//! A random rotation (QR of a Gaussian matrix via the SVD's U).
gm::Mat3 random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  gm::Mat3 A, U, V;
  gm::Vec3 s;
  for (double& a : A.a) a = g(rng);
  gm::svd3(A, U, s, V);
  return U;
}

}  // namespace

TEST(ElastogenKernels, FactoredGradientsAndForcesMatchTheStencil) {
  const elastogen::HexStencil& hs = elastogen::HexStencil::get();
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const double h = 0.05, inv_h = 1.0 / h, scale = h * h * h / 8.0 * inv_h;
  for (int trial = 0; trial < 200; ++trial) {
    double xe[8][3];
    for (int l = 0; l < 8; ++l)
      for (int a = 0; a < 3; ++a) xe[l][a] = 3.0 + h * ((l >> a) & 1) + 0.2 * h * u(rng);
    double F[8][9], Fr[8][9];
    elastogen::HexGauss::gradients(xe, inv_h, F);
    for (int q = 0; q < 8; ++q) elastogen::deformation_gradient(hs, q, xe, inv_h, Fr[q]);
    double err = 0;
    for (int q = 0; q < 8; ++q)
      for (int a = 0; a < 9; ++a) err = std::max(err, std::fabs(F[q][a] - Fr[q][a]));
    // The reference sums 8 corner terms of size |x| / h = 60 per entry: rounding ~1e-14.
    EXPECT_LE(err, 1e-12) << "trial " << trial;

    double P[8][9], fe[8][3], fr[8][3] = {};
    for (int q = 0; q < 8; ++q)
      for (int a = 0; a < 9; ++a) P[q][a] = 1e5 * u(rng);
    elastogen::HexGauss::forces(P, scale, fe);
    for (int q = 0; q < 8; ++q) elastogen::add_node_forces(hs, q, P[q], scale, fr);
    double ferr = 0;
    for (int l = 0; l < 8; ++l)
      for (int a = 0; a < 3; ++a) ferr = std::max(ferr, std::fabs(fe[l][a] - fr[l][a]));
    EXPECT_LE(ferr, 1e-13 * max_abs(&fr[0][0], 24) + 1e-15 * 1e5 * scale) << "trial " << trial;
  }
}

TEST(ElastogenKernels, PolarCorotatedStressMatchesTheSvdPath) {
  const auto law = gm::FixedCorotated::from_young_poisson(1e6, 0.3);
  const elastogen::CorotatedPolarStress fast{law};
  const double modulus = 2.0 * law.mu + std::fabs(law.lambda);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int fallbacks = 0;
  for (double stretch : {1e-5, 1e-3, 1e-2, 0.1, 0.5}) {
    for (int trial = 0; trial < 200; ++trial) {
      // F = Q diag(s) W^T with log-stretches up to `stretch`; every 10th inverted.
      gm::Vec3 s{
          {std::exp(stretch * u(rng)), std::exp(stretch * u(rng)), std::exp(stretch * u(rng))}};
      if (trial % 10 == 9) s[2] = -s[2];
      const gm::Mat3 F = random_rotation(rng) * gm::diag3(s) * gm::transpose(random_rotation(rng));
      gm::Mat3 Pr, R;
      const double psi_r = law.energy_and_pk1(F, Pr);
      double P[9];
      const double psi = fast(F.a, P);
      const double f2 = gm::frobenius_norm(F) * gm::frobenius_norm(F);
      double err = 0;
      for (int a = 0; a < 9; ++a) err = std::max(err, std::fabs(P[a] - Pr.a[a]));
      EXPECT_LE(err, 1e-12 * modulus * f2) << "stretch " << stretch << " trial " << trial;
      EXPECT_LE(std::fabs(psi - psi_r), 1e-12 * modulus * f2)
          << "stretch " << stretch << " trial " << trial;
      if (!elastogen::polar_rotation_near(F, gm::cofactor(F), gm::det(F), R)) {
        ++fallbacks;
        // The signed-SVD path itself: the same numbers bit for bit.
        for (int a = 0; a < 9; ++a) EXPECT_EQ(P[a], Pr.a[a]);
        EXPECT_EQ(psi, psi_r);
      }
    }
  }
  EXPECT_EQ(fallbacks, 5 * 20);  // exactly the inverted points
  // ARAP through the same rotation.
  const auto arap = gm::Arap::from_young_poisson(1e6, 0.3);
  const elastogen::ArapPolarStress fast_arap{arap};
  for (int trial = 0; trial < 200; ++trial) {
    gm::Vec3 s{{std::exp(0.05 * u(rng)), std::exp(0.05 * u(rng)), std::exp(0.05 * u(rng))}};
    const gm::Mat3 F = random_rotation(rng) * gm::diag3(s) * gm::transpose(random_rotation(rng));
    gm::Mat3 Pr;
    const double psi_r = arap.energy_and_pk1(F, Pr);
    double P[9];
    const double psi = fast_arap(F.a, P);
    for (int a = 0; a < 9; ++a) EXPECT_NEAR(P[a], Pr.a[a], 1e-12 * arap.k) << trial;
    EXPECT_NEAR(psi, psi_r, 1e-12 * arap.k) << trial;
  }
}

TEST(ElastogenKernels, SweepIsBitIdenticalAcrossThreadsAndEqualsThePointwiseKernel) {
  test::KernelScene s = test::kernel_scene();
  elastogen::VoxelSystem& sys = *s.sys;
  const std::size_t n = s.d.size();
  const double omega = 0.67;
  std::vector<double> d1(n, 0.0), res1(n, 0.0), a1(n, 0.0);
  set_threads(1);
  sys.jacobi_sweep(s.k, s.inv_dt2, omega, s.r.data(), s.diag.data(), s.d.data(), d1.data(),
                   res1.data());
  sys.apply(s.k, s.inv_dt2, s.d.data(), a1.data());
  EXPECT_GT(max_abs(res1.data(), n), 0.1);
  for (int threads : {2, 3}) {
    std::vector<double> dt(n, 0.0), rt(n, 0.0), at(n, 0.0);
    set_threads(threads);
    sys.jacobi_sweep(s.k, s.inv_dt2, omega, s.r.data(), s.diag.data(), s.d.data(), dt.data(),
                     rt.data());
    sys.apply(s.k, s.inv_dt2, s.d.data(), at.data());
    long differ = 0;
    for (std::size_t q = 0; q < n; ++q)
      differ += (dt[q] != d1[q]) + (rt[q] != res1[q]) + (at[q] != a1[q]);
    EXPECT_EQ(differ, 0) << threads << " threads";
  }
  set_threads(1);
  // The per-value kernel (what the GPU runs) over the owned values.
  std::vector<double> dk(n, 0.0), rk(n, 0.0);
  const auto kern = sys.jacobi_kernel(s.k, s.inv_dt2, omega, s.r.data(), s.diag.data(),
                                      sys.mass().data(), sys.free_mask().data(),
                                      sys.adjacency().data(), s.d.data(), dk.data(), rk.data());
  exec::parallel_for(kern.values(), kern);
  double worst_d = 0, worst_r = 0;
  long interior = 0, general = 0, held = 0;
  const double interior_mass = sys.mass()[sys.ghosted().index(3, 3, 3)];
  elastogen::for_owned(sys.owned(), sys.ghosted(), [&](std::size_t nn, long, long, long) {
    if (!sys.free_mask()[nn])
      held += sys.fixed_mask()[nn];
    else if (sys.adjacency()[nn] == 0xFF && sys.mass()[nn] == interior_mass)
      ++interior;
    else
      ++general;
    for (int d = 0; d < 3; ++d) {
      worst_d = std::max(worst_d, std::fabs(dk[3 * nn + d] - d1[3 * nn + d]));
      worst_r = std::max(worst_r, std::fabs(rk[3 * nn + d] - res1[3 * nn + d]));
    }
  });
  // Both paths round every product and sum alike where the build has no fused multiply-add.
#if defined(__FMA__)
  EXPECT_LE(worst_d, 1e-15 * max_abs(d1.data(), n));
  EXPECT_LE(worst_r, 1e-12 * max_abs(res1.data(), n));
#else
  EXPECT_EQ(worst_d, 0.0);
  EXPECT_EQ(worst_r, 0.0);
#endif
  EXPECT_GT(interior, 1000);
  EXPECT_GT(general, 500);
  EXPECT_GT(held, 50);
}

TEST(ElastogenKernels, LocalStepIsBitIdenticalAcrossThreadsAndMatchesTheSvdPath) {
  test::KernelScene s = test::kernel_scene();
  elastogen::VoxelSystem& sys = *s.sys;
  const parallel::Box& G = sys.ghosted();
  std::vector<double> x(3 * G.size());
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (long k = G.start[2]; k < G.start[2] + G.count[2]; ++k)
    for (long j = G.start[1]; j < G.start[1] + G.count[1]; ++j)
      for (long i = G.start[0]; i < G.start[0] + G.count[0]; ++i) {
        const auto p = sys.rest_position(i, j, k);
        // A bend about y plus noise: rotations up to ~0.3 rad, strains ~1e-2.
        const double th = 0.3 * p[0] / 1.2;
        const std::size_t q = 3 * G.index(i, j, k);
        x[q] = p[0] * std::cos(th) + p[2] * std::sin(th) + 5e-4 * u(rng);
        x[q + 1] = p[1] + 5e-4 * u(rng);
        x[q + 2] = -p[0] * std::sin(th) + p[2] * std::cos(th) + 5e-4 * u(rng);
      }
  const auto law = gm::FixedCorotated::from_young_poisson(1e6, 0.3);
  const elastogen::CorotatedPolarStress fast{law};
  const std::size_t n = x.size();
  std::vector<double> f1(n, 0.0);
  set_threads(1);
  const double e1 = sys.internal_forces(fast, x.data(), f1.data()).value();
  EXPECT_GT(e1, 0.0);
  for (int threads : {2, 3}) {
    std::vector<double> ft(n, 0.0);
    set_threads(threads);
    const double et = sys.internal_forces(fast, x.data(), ft.data()).value();
    EXPECT_EQ(et, e1) << threads << " threads";
    long differ = 0;
    for (std::size_t q = 0; q < n; ++q) differ += ft[q] != f1[q];
    EXPECT_EQ(differ, 0) << threads << " threads";
  }
  set_threads(1);
  // The SVD path of the same law: the same forces and energy to rounding.
  const auto svd = [&](const double* F, double* P) {
    gm::Mat3 Fm, Pm;
    for (int a = 0; a < 9; ++a) Fm.a[a] = F[a];
    const double psi = law.energy_and_pk1(Fm, Pm);
    for (int a = 0; a < 9; ++a) P[a] = Pm.a[a];
    return psi;
  };
  std::vector<double> fs(n, 0.0);
  const double es = sys.internal_forces(svd, x.data(), fs.data()).value();
  double err = 0;
  for (std::size_t q = 0; q < n; ++q) err = std::max(err, std::fabs(fs[q] - f1[q]));
  EXPECT_LE(err, 1e-9 * max_abs(fs.data(), n));
  EXPECT_LE(std::fabs(es - e1), 1e-9 * es);
}
