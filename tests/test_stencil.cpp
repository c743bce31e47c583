// The 2x2x2 Gauss-point voxel stencil has no hourglass modes: on a free block of voxels the
// only zero-energy displacements are the 6 rigid ones, and a checkerboard costs energy.
#include <gtest/gtest.h>
#include <mpi.h>

#include <Eigen/Dense>

#include <vector>

#include "elastogen/VoxelSystem.hpp"
#include "materials/LinearElastic.hpp"

using namespace gen4d;
namespace gm = gen4d::materials;

namespace {
// Linear elasticity makes the internal force linear in x, so K e_i = f(x0) - f(x0 + e_i).
Eigen::MatrixXd block_stiffness(long cells) {
  const long n = cells + 1;
  parallel::NodeGrid grid(MPI_COMM_SELF, {n, n, n});
  std::vector<std::uint8_t> occ(grid.adjacent_cells().size(), 1);
  elastogen::VoxelSystem sys(grid, {0, 0, 0}, 0.1, occ, {1000.0}, {});
  const auto mat = gm::LinearElastic::from_young_poisson(1e6, 0.3);
  auto stress = [&](const double* F, double* P) {
    gm::Mat3 Fm, Pm;
    for (int a = 0; a < 9; ++a) Fm.a[a] = F[a];
    const double psi = mat.energy_and_pk1(Fm, Pm);
    for (int a = 0; a < 9; ++a) P[a] = Pm.a[a];
    return psi;
  };
  const parallel::Box& G = grid.ghosted_nodes();
  const long dofs = 3 * G.size();
  std::vector<double> x0(dofs), f0(dofs), x(dofs), f(dofs);
  for (long k = 0; k < n; ++k)
    for (long j = 0; j < n; ++j)
      for (long i = 0; i < n; ++i) {
        const auto p = sys.rest_position(i, j, k);
        for (int d = 0; d < 3; ++d) x0[3 * G.index(i, j, k) + d] = p[d];
      }
  sys.internal_forces(stress, x0.data(), f0.data());
  Eigen::MatrixXd K(dofs, dofs);
  for (long c = 0; c < dofs; ++c) {
    x = x0;
    x[c] += 1e-3;
    sys.internal_forces(stress, x.data(), f.data());
    for (long r = 0; r < dofs; ++r) K(r, c) = (f0[r] - f[r]) / 1e-3;
  }
  return K;
}
}  // namespace

TEST(VoxelStencil, FreeBlockHasExactlySixZeroEnergyModes) {
  for (long cells : {1L, 2L}) {
    const Eigen::MatrixXd K = block_stiffness(cells);
    EXPECT_LT((K - K.transpose()).norm(), 1e-6 * K.norm());
    const Eigen::VectorXd ev =
        Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(0.5 * (K + K.transpose())).eigenvalues();
    const double scale = ev.cwiseAbs().maxCoeff();
    int zero = 0;
    for (int i = 0; i < ev.size(); ++i) {
      EXPECT_GT(ev(i), -1e-9 * scale);  // positive semi-definite
      zero += ev(i) < 1e-9 * scale;
    }
    std::printf("[ stencil ] %ld^3 voxels: %d zero modes of %ld, smallest non-zero %.3e of %.3e\n",
                cells, zero, static_cast<long>(ev.size()), ev(zero), scale);
    EXPECT_EQ(zero, 6) << cells << "^3 voxels";
  }
}

TEST(VoxelStencil, CheckerboardDisplacementCostsEnergy) {
  // The one-point (voxel-centre) rule sees zero strain for this pattern; 2x2x2 Gauss does not.
  const long n = 4;
  const Eigen::MatrixXd K = block_stiffness(n - 1);
  Eigen::VectorXd u = Eigen::VectorXd::Zero(K.rows());
  for (long k = 0; k < n; ++k)
    for (long j = 0; j < n; ++j)
      for (long i = 0; i < n; ++i) u(3 * ((k * n + j) * n + i)) = ((i + j + k) % 2 ? 1.0 : -1.0);
  const double checker = 0.5 * u.dot(K * u) / u.squaredNorm();
  // Compare with a smooth stretch of the same amplitude.
  Eigen::VectorXd s = Eigen::VectorXd::Zero(K.rows());
  for (long k = 0; k < n; ++k)
    for (long j = 0; j < n; ++j)
      for (long i = 0; i < n; ++i) s(3 * ((k * n + j) * n + i)) = (2.0 * i / (n - 1) - 1.0);
  const double stretch = 0.5 * s.dot(K * s) / s.squaredNorm();
  std::printf("[ stencil ] energy per unit amplitude^2: checkerboard %.3e, stretch %.3e\n", checker,
              stretch);
  // Same order as a smooth stretch, nowhere near the zero a hourglass mode would give.
  EXPECT_GT(checker, 0.5 * stretch);
  // The voxel-centre gradient of the pattern vanishes: one-point quadrature would miss it.
  double centre_gradient = 0;
  for (int l = 0; l < 8; ++l) {
    const int a = l & 1, b = (l >> 1) & 1, c = (l >> 2) & 1;
    const double sign = (a + b + c) % 2 ? 1.0 : -1.0;
    centre_gradient += sign * (2 * a - 1) * 0.25;  // d N_l / d xi_x at the centre
  }
  EXPECT_EQ(centre_gradient, 0.0);
}
