// Splats as MPM particles: the splat attributes follow the flow identically at 1, 2 and 4
// ranks, survive a checkpoint and a restart at another rank count bit for bit, get
// PhysGaussian's volumes, and a rigid rotation turns F_tot and the covariances by the rotation.
#include <gtest/gtest.h>
#include <mpi.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <vector>

#include "gaussians/Kinematics.hpp"
#include "mpm/ParticleIO.hpp"
#include "mpm/Seeding.hpp"
#include "mpm/Solver.hpp"
#include "mpm/SplatParticles.hpp"
#include "parallel/Distribute.hpp"
#include "mpm_test_util.hpp"
#include "mpi_test_util.hpp"

namespace gen4d {
namespace {

using test::grid;

using test::rank_of;
using test::size_of;

//! `n` splats of SH degree 1 uniformly in the box [lo, hi], random orientations and sizes.
gaussians::SplatSet synthetic_splats(std::size_t n, const Vec3d& lo, const Vec3d& hi) {
  std::mt19937_64 rng(20240607);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  gaussians::SplatSet s;
  s.sh_degree = 1;
  for (std::size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) s.position.push_back(lo[a] + (hi[a] - lo[a]) * u(rng));
    for (int a = 0; a < 3; ++a) s.scale.push_back(0.002 + 0.01 * u(rng));
    double q[4], norm = 0;
    for (double& c : q) {
      c = g(rng);
      norm += c * c;
    }
    for (double c : q) s.rotation.push_back(c / std::sqrt(norm));
    s.opacity.push_back(0.1 + 0.85 * u(rng));
    for (int k = 0; k < 12; ++k) s.sh.push_back(g(rng));
  }
  return s;
}

const gaussians::SplatSet& block_splats() {
  static const gaussians::SplatSet s = synthetic_splats(3000, {0, 0, 0.02}, {0.25, 0.2, 0.3});
  return s;
}

mpm::SolverOptions falling_options() {
  mpm::SolverOptions opt;
  opt.max_dt = 2e-3;
  return opt;
}

std::vector<BoundaryConfig> floor_collider() {
  return {mpm::surface_collider("separate", {0, 0, 0}, {0, 0, 1}, 0.4)};
}

//! Every particle's id, solver record and extra values in id order, on rank 0 of `comm`.
struct Gathered {
  std::vector<std::int64_t> id;
  std::vector<double> record;  // kRecord per particle
  std::vector<double> extra;
  int width = 0;
};

Gathered gather(MPI_Comm comm, const mpm::Particles& p) {
  Gathered g;
  g.width = p.extra_width;
  std::vector<std::int64_t> id = p.id;
  std::vector<double> record(p.size() * mpm::Particles::kRecord), extra = p.extra;
  for (std::size_t i = 0; i < p.size(); ++i) p.pack(i, &record[i * mpm::Particles::kRecord]);
  parallel::RowExchange ex;
  ex.add(id, 1).add(record, mpm::Particles::kRecord).add(extra, p.extra_width);
  ex.exchange(comm, std::vector<int>(id.size(), 0));
  std::vector<std::size_t> order(id.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](auto a, auto b) { return id[a] < id[b]; });
  const auto W = static_cast<std::size_t>(g.width);
  for (std::size_t i : order) {
    g.id.push_back(id[i]);
    g.record.insert(g.record.end(), &record[i * mpm::Particles::kRecord],
                    &record[(i + 1) * mpm::Particles::kRecord]);
    g.extra.insert(g.extra.end(), extra.begin() + static_cast<long>(W * i),
                   extra.begin() + static_cast<long>(W * (i + 1)));
  }
  return g;
}

long differing(const Gathered& a, const Gathered& b) {
  if (a.id != b.id || a.record.size() != b.record.size() || a.extra.size() != b.extra.size())
    return -1;
  long n = 0;
  for (std::size_t k = 0; k < a.record.size(); ++k) n += a.record[k] != b.record[k];
  for (std::size_t k = 0; k < a.extra.size(); ++k) n += a.extra[k] != b.extra[k];
  return n;
}

//! A solver on `comm` with the block of splats seeded, or (restart) the given particles.
std::unique_ptr<mpm::Solver> make_solver(MPI_Comm comm, const mpm::SolverOptions& opt,
                                         const std::vector<BoundaryConfig>& bcs,
                                         const gaussians::SplatSet& splats) {
  auto m = test::jelly();
  auto s = std::make_unique<mpm::Solver>(comm, grid(), m, opt, bcs);
  s->distribute(mpm::seed_splats(comm, grid(), splats, *m, {0.2, 0, -0.8}, 0));
  return s;
}

void advance(mpm::Solver& s, const mpm::SplatLayout& layout, mpm::CovarianceUpdate mode,
             int substeps, double& t) {
  for (int k = 0; k < substeps; ++k) {
    const double dt = s.stable_dt(1.0);
    s.substep(t, dt);
    mpm::advance_splats(s.particles(), layout, dt, mode);
    t += dt;
  }
}

TEST(MpmSplats, SeedingGivesCellVolumesAndDenseIds) {
  const auto& splats = block_splats();
  auto m = test::jelly();
  const mpm::Particles p = mpm::seed_splats(MPI_COMM_WORLD, grid(), splats, *m, {0, 0, 0}, 7);
  const mpm::SplatLayout layout{1};
  ASSERT_EQ(p.extra_width, layout.width());
  ASSERT_EQ(p.inconsistency(), "");
  // Expected per-cell counts straight from the positions.
  const auto g = grid();
  std::map<std::array<long, 3>, int> count;
  auto cell_of = [&](const double* x) {
    std::array<long, 3> c;
    for (int a = 0; a < 3; ++a) c[a] = static_cast<long>(std::floor((x[a] - g.lo[a]) / g.dx));
    return c;
  };
  for (std::size_t i = 0; i < splats.size(); ++i) ++count[cell_of(&splats.position[3 * i])];
  const double cell = g.dx * g.dx * g.dx;
  double volume = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const auto s = static_cast<std::size_t>(p.id[i] - 7);
    ASSERT_LT(s, splats.size());
    EXPECT_EQ(p.x[3 * i], splats.position[3 * s]);
    EXPECT_EQ(p.vol0[i], cell / count[cell_of(&p.x[3 * i])]);
    EXPECT_EQ(p.mass[i], 1000 * p.vol0[i]);
    EXPECT_EQ(p.extra[layout.width() * i + mpm::SplatLayout::kOpacity], splats.opacity[s]);
    volume += p.vol0[i];
  }
  long long n = static_cast<long long>(p.size()), total = 0;
  MPI_Allreduce(&n, &total, 1, MPI_LONG_LONG, MPI_SUM, MPI_COMM_WORLD);
  EXPECT_EQ(total, static_cast<long long>(splats.size()));
  double sum = 0;
  MPI_Allreduce(&volume, &sum, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  // The volumes add up to the occupied cells' volume.
  EXPECT_NEAR(sum, static_cast<double>(count.size()) * cell, 1e-12 * sum);
  EXPECT_GT(count.size(), 20u);
  // Ids are dense in splat order.
  std::int64_t lo = p.size() ? p.id.front() : 0;
  for (std::size_t i = 0; i < p.size(); ++i) EXPECT_EQ(p.id[i], lo + static_cast<long>(i));
}

TEST(MpmSplats, SplatOutsideTheGridIsAnInputError) {
  gaussians::SplatSet s = synthetic_splats(10, {0, 0, 0}, {0.1, 0.1, 0.1});
  s.position[3 * 4 + 2] = 5.0;
  auto m = test::jelly();
  EXPECT_THROW(mpm::seed_splats(MPI_COMM_WORLD, grid(), s, *m, {0, 0, 0}, 0, 0, "deck.toml"),
               InputError);
}

//! Falling block on a floor: the splat states at this rank count equal a serial run's bit for
//! bit, in both covariance modes.
TEST(MpmSplats, SplatStatesBitIdenticalAcrossRankCounts) {
  const mpm::SplatLayout layout{1};
  for (auto mode : {mpm::CovarianceUpdate::Rate, mpm::CovarianceUpdate::DeformationGradient}) {
    double t = 0;
    auto dist = make_solver(MPI_COMM_WORLD, falling_options(), floor_collider(), block_splats());
    advance(*dist, layout, mode, 60, t);
    const Gathered a = gather(MPI_COMM_WORLD, dist->particles());
    if (rank_of(MPI_COMM_WORLD) != 0) continue;
    double ts = 0;
    auto serial = make_solver(MPI_COMM_SELF, falling_options(), floor_collider(), block_splats());
    advance(*serial, layout, mode, 60, ts);
    const Gathered b = gather(MPI_COMM_SELF, serial->particles());
    ASSERT_EQ(a.id.size(), block_splats().size());
    EXPECT_EQ(t, ts);
    EXPECT_EQ(differing(a, b), 0);
    // The block really deformed: F_tot and the covariance left their rest values.
    const int W = layout.width();
    double dF = 0, dcov = 0;
    for (std::size_t i = 0; i < a.id.size(); ++i) {
      const double* e = &a.extra[W * i];
      for (int k = 0; k < 9; ++k)
        dF = std::max(dF, std::abs(e[mpm::SplatLayout::kF + k] - (k % 4 == 0 ? 1.0 : 0.0)));
      double rest[64];
      mpm::splat_rest_values(block_splats(), static_cast<std::size_t>(a.id[i]), layout, rest);
      for (int k = 0; k < 6; ++k)
        dcov = std::max(dcov, std::abs(e[mpm::SplatLayout::kCovariance + k] -
                                       rest[mpm::SplatLayout::kCovariance + k]));
    }
    EXPECT_GT(dF, 1e-3);
    if (mode == mpm::CovarianceUpdate::Rate) {
      EXPECT_GT(dcov, 1e-9);
    } else {
      EXPECT_EQ(dcov, 0.0);  // only the rate form updates it
    }
  }
}

//! Checkpoint at min(2, P) ranks, restart at P ranks and at 1: both continue bit-identically.
TEST(MpmSplats, CheckpointRestartAtOtherRankCountsIsBitIdentical) {
  const mpm::SplatLayout layout{1};
  const auto mode = mpm::CovarianceUpdate::Rate;
  const int rank = rank_of(MPI_COMM_WORLD), size = size_of(MPI_COMM_WORLD);
  const std::string dir =
      std::string(GEN4D_BINARY_DIR) + "/test_mpm_splats_np" + std::to_string(size);
  MPI_Comm writers;
  MPI_Comm_split(MPI_COMM_WORLD, rank < 2 ? 0 : MPI_UNDEFINED, rank, &writers);
  std::string path;
  Gathered reference;
  double t_end = 0;
  if (writers != MPI_COMM_NULL) {
    double t = 0;
    auto s = make_solver(writers, falling_options(), floor_collider(), block_splats());
    advance(*s, layout, mode, 25, t);
    mpm::ParticleCheckpointState st;
    st.step = 25;
    st.time = t;
    st.total_particles = static_cast<std::int64_t>(block_splats().size());
    st.extra_names = layout.names();
    st.particles = &s->particles();
    path = mpm::write_particle_checkpoint(writers, dir, st, 0);
    advance(*s, layout, mode, 25, t);
    reference = gather(writers, s->particles());
    t_end = t;
    MPI_Comm_free(&writers);
  }
  // Rank 0 shares the path.
  unsigned long len = path.size();
  MPI_Bcast(&len, 1, MPI_UNSIGNED_LONG, 0, MPI_COMM_WORLD);
  path.resize(len);
  MPI_Bcast(path.data(), static_cast<int>(len), MPI_CHAR, 0, MPI_COMM_WORLD);

  auto restart = [&](MPI_Comm comm) {
    mpm::Particles p;
    const auto meta = mpm::read_particle_checkpoint(comm, path, p);
    EXPECT_EQ(meta.extra_names, layout.names());
    EXPECT_EQ(p.extra_width, layout.width());
    EXPECT_EQ(mpm::SplatLayout::from_names(meta.extra_names, path).sh_degree, 1);
    auto s = std::make_unique<mpm::Solver>(comm, grid(), test::jelly(), falling_options(),
                                           floor_collider());
    s->distribute(std::move(p));
    double t = meta.time;
    advance(*s, layout, mode, 25, t);
    EXPECT_EQ(t, rank_of(comm) == 0 && rank == 0 ? t_end : t);
    return gather(comm, s->particles());
  };
  const Gathered world = restart(MPI_COMM_WORLD);
  if (rank == 0) {
    ASSERT_EQ(reference.id.size(), block_splats().size());
    EXPECT_EQ(differing(world, reference), 0) << "restart at " << size << " ranks";
    const Gathered serial = restart(MPI_COMM_SELF);
    EXPECT_EQ(differing(serial, reference), 0) << "restart at 1 rank";
  }
}

//! A rigid rotation about z at w for T: the polar rotation of F_tot is the rotation by w T, and
//! the drawn covariances are R A0 R^T.
TEST(MpmSplats, RigidRotationTurnsFAndCovariances) {
  const auto splats = synthetic_splats(400, {0.05, 0.05, 0.05}, {0.2, 0.15, 0.2});
  const mpm::SplatLayout layout{1};
  BoundaryConfig spin;
  spin.type = "enforce_particle_velocity_rotation";
  spin.point = {0.125, 0.1, 0.125};
  spin.normal = {0, 0, 1};
  spin.radius = 1;
  spin.half_height = 1;
  const double w = 2.0, dt = 1e-3;
  const int steps = 500;
  spin.angular_velocity = {0, 0, w};
  mpm::SolverOptions opt;
  opt.gravity = {0, 0, 0};
  opt.adaptive = false;
  opt.max_dt = dt;
  for (auto mode : {mpm::CovarianceUpdate::DeformationGradient, mpm::CovarianceUpdate::Rate}) {
    auto m = test::jelly();
    mpm::Solver s(MPI_COMM_WORLD, grid(), m, opt, {spin});
    s.distribute(mpm::seed_splats(MPI_COMM_WORLD, grid(), splats, *m, {0, 0, 0}, 0));
    double t = 0;
    for (int k = 0; k < steps; ++k) {
      s.substep(t, dt);
      mpm::advance_splats(s.particles(), layout, dt, mode);
      t += dt;
    }
    const double theta = w * steps * dt;
    const Eigen::Matrix3d exact =
        Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const mpm::Particles& p = s.particles();
    const gaussians::SplatFrame frame =
        mpm::splat_frame(p, layout, gaussians::KinematicsOptions{}, mode);
    ASSERT_EQ(frame.size(), p.size());
    double angle_error = 0, cov_error = 0;
    for (std::size_t i = 0; i < p.size(); ++i) {
      const double* e = &p.extra[layout.width() * i];
      std::array<double, 9> F;
      std::copy_n(e + mpm::SplatLayout::kF, 9, F.begin());
      const auto R = gaussians::polar_rotation(F);
      angle_error = std::max(angle_error, std::abs(std::atan2(R[3], R[0]) - theta));
      // R A0 R^T with A0 from the splat's rest shape.
      double rest[64];
      mpm::splat_rest_values(splats, static_cast<std::size_t>(p.id[i]), layout, rest);
      const double* a0 = rest + mpm::SplatLayout::kCovariance;
      Eigen::Matrix3d A0;
      A0 << a0[0], a0[1], a0[2], a0[1], a0[3], a0[4], a0[2], a0[4], a0[5];
      const Eigen::Matrix3d turned = exact * A0 * exact.transpose();
      const float* c = &frame.covariance[6 * i];
      Eigen::Matrix3d drawn;
      drawn << c[0], c[1], c[2], c[1], c[3], c[4], c[2], c[4], c[5];
      cov_error = std::max(cov_error, (drawn - turned).norm() / A0.norm());
    }
    // Per substep F_tot turns by atan(w dt) and stretches by sqrt(1 + (w dt)^2): after n
    // substeps the angle is off by about n (w dt)^3 / 3 (1.3e-6 rad) and the covariance by
    // about n (w dt)^2 (2e-3 relative).
    if (rank_of(MPI_COMM_WORLD) == 0)
      std::printf("rotation by %.3f rad (%s): angle error %.3g rad, covariance error %.3g\n", theta,
                  mode == mpm::CovarianceUpdate::Rate ? "rate" : "F", angle_error, cov_error);
    EXPECT_LT(angle_error, 1e-5);
    EXPECT_LT(cov_error, 3e-3);
    EXPECT_GT(theta, 0.9);
  }
}

}  // namespace
}  // namespace gen4d
