// 3D Gaussian splats riding ElastoGen's voxels: independence of the rank count, rigid and affine
// motion reproduced exactly, voxels from splat objects, and rendered frames.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>

#include "elastogen/SplatEmbedding.hpp"
#include "deck_test_util.hpp"
#include "elastogen_test_util.hpp"
#include "gaussians/DeckSplats.hpp"
#include "gaussians/Ply.hpp"
#include "gaussians/Video.hpp"
#include "io/Checkpoint.hpp"
#include "png_test_util.hpp"

using namespace gen4d;
namespace fs = std::filesystem;

namespace {

using test::scratch_dir;

// A block clamped at x = 0; the splat ball added by the tests overlaps its far end.
const std::string kDeck = test::TestDeck()
                              .simulation(0.01, 0.03, {{"gravity", "[0, 0, -9.81]"}})
                              .domain(0.02)
                              .box({0, 0.02, 0.02}, {0.08, 0.08, 0.08})
                              .material(5.0e4, 0.3, 1000)
                              .table("solver", {{"max_sweeps", "40"}})
                              .clamp()
                              .region("force", {0.1, -1, -1}, {1, 1, 1}, {{"force", "[0, 3, -6]"}})
                              .table("output", {{"progress_interval", "1e9"}});

//! Deterministic numbers in [0, 1) (64-bit LCG, top 53 bits).
struct Lcg {
  std::uint64_t s;
  double next() {
    s = s * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(s >> 11) * (1.0 / 9007199254740992.0);
  }
};

//! `n` splats filling a ball of `radius` about `center`: random orientations and anisotropic
//! scales, SH degree 1 (so degree-0 splats of other parts are raised to it).
gaussians::SplatSet splat_ball(long n, const std::array<double, 3>& center, double radius) {
  gaussians::SplatSet s;
  s.sh_degree = 1;
  Lcg rng{12345};
  while (static_cast<long>(s.size()) < n) {
    double p[3];
    for (double& c : p) c = 2 * rng.next() - 1;
    if (p[0] * p[0] + p[1] * p[1] + p[2] * p[2] > 1) continue;
    for (int d = 0; d < 3; ++d) s.position.push_back(center[d] + radius * p[d]);
    for (int d = 0; d < 3; ++d) s.scale.push_back(0.002 + 0.004 * rng.next());
    double q[4], norm = 0;
    for (double& c : q) {
      c = 2 * rng.next() - 1;
      norm += c * c;
    }
    for (double c : q) s.rotation.push_back(c / std::sqrt(norm));
    s.opacity.push_back(0.3 + 0.6 * rng.next());
    for (int k = 0; k < 3 * 4; ++k) s.sh.push_back(k < 3 ? rng.next() : 0.2 * (rng.next() - 0.5));
  }
  return s;
}

//! The block deck with a splat ball (written to `dir`) of `n` splats as its second part.
Config ball_deck(const std::string& dir, long n, const std::vector<std::string>& sets = {}) {
  const std::string ply = dir + "/ball.ply";
  if (test::world_rank() == 0)
    gaussians::write_splats_ply(ply, splat_ball(n, {0.12, 0.05, 0.05}, 0.05));
  MPI_Barrier(MPI_COMM_WORLD);
  Config cfg = parse_deck(kDeck, "<splats>", ".", sets);
  GeometryConfig g;
  g.type = "splats";
  g.file = ply;
  cfg.geometry.push_back(g);
  return cfg;
}

//! Splat means and deformation gradients of a simulation, on rank 0.
struct Gathered {
  std::vector<double> x, F;
};
Gathered gather_splats(elastogen::Simulation& sim) {
  Gathered g;
  sim.splats()->gather(sim.dynamics().x().data(), g.x, g.F);
  return g;
}

using test::bytes_of;
using test::node_field;

}  // namespace

TEST(ElastogenSplats, SplatPartBecomesSolidVoxelsAndEverySplatIsEmbedded) {
  const std::string dir = scratch_dir("elastogen_splats_voxels");
  const Config cfg = ball_deck(dir, 3000);
  const elastogen::DeckObject obj = elastogen::build_deck_object(cfg);
  ASSERT_TRUE(obj.has_splat_parts);
  // The box's splats (degree 0, raised to 1) come first, then the ball's 3000, in deck order.
  const gaussians::SplatSet box = gaussians::splats_from_shape(
      *geometry::make_shape({cfg.geometry[0]}), 0.01, cfg.geometry[0].color);
  ASSERT_EQ(obj.splats.size(), box.size() + 3000);
  EXPECT_EQ(obj.splats.sh_degree, 1);
  EXPECT_EQ(obj.splats.sh.size(), 12 * obj.splats.size());
  for (std::size_t i = 0; i < box.size(); ++i) {
    for (int c = 0; c < 3; ++c) EXPECT_EQ(obj.splats.sh[12 * i + c], box.sh[3 * i + c]);
    for (int k = 3; k < 12; ++k) EXPECT_EQ(obj.splats.sh[12 * i + k], 0.0);
  }
  // The ball's voxels are solid: every voxel centre within the ball less a voxel diagonal is
  // inside the union, and nothing beyond the ball and the box.
  int inside = 0, outside = 0;
  for (double x = 0.085; x < 0.2; x += 0.02)
    for (double y = -0.005; y < 0.11; y += 0.02)
      for (double z = -0.005; z < 0.11; z += 0.02) {
        const double r = std::hypot(x - 0.12, y - 0.05, z - 0.05);
        const bool in = obj.shape->inside(Eigen::Vector3d(x, y, z));
        if (r < 0.05 - 0.035) inside += in ? 0 : 1;
        if (r > 0.05 + 0.035) outside += in ? 1 : 0;
      }
  EXPECT_EQ(inside, 0);
  EXPECT_EQ(outside, 0);

  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
  const elastogen::SplatEmbedding* s = sim.splats();
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->count(), static_cast<long>(obj.splats.size()));
  // A splat part's occupancy holds every splat's mean; only box splats can miss solid voxels.
  const Gathered rest = gather_splats(sim);
  if (test::world_rank() != 0) return;
  ASSERT_EQ(rest.x.size(), 3 * obj.splats.size());
  for (std::size_t i = 0; i < obj.splats.size(); ++i) {
    for (int d = 0; d < 3; ++d)
      ASSERT_NEAR(rest.x[3 * i + d], obj.splats.position[3 * i + d], 1e-15) << i;
    for (int e = 0; e < 9; ++e) ASSERT_NEAR(rest.F[9 * i + e], e % 4 == 0 ? 1.0 : 0.0, 1e-13) << i;
  }
}

TEST(ElastogenSplats, MeansAndGradientsAreBitIdenticalAcrossRankCounts) {
  const std::string dir = scratch_dir("elastogen_splats_ranks");
  const Config cfg = ball_deck(dir, 3000);
  const int steps = 3;
  elastogen::Simulation dist(MPI_COMM_WORLD, cfg);
  for (int s = 0; s < steps; ++s) dist.dynamics().step(s * cfg.dt);
  const Gathered d = gather_splats(dist);
  if (test::world_rank() != 0) return;
  elastogen::Simulation serial(MPI_COMM_SELF, cfg);
  for (int s = 0; s < steps; ++s) serial.dynamics().step(s * cfg.dt);
  const Gathered r = gather_splats(serial);
  ASSERT_EQ(d.x.size(), r.x.size());
  ASSERT_EQ(d.F.size(), r.F.size());
  ASSERT_EQ(d.x.size(), 3 * static_cast<std::size_t>(dist.splats()->count()));
  long differ = 0;
  double strain = 0, moved = 0;
  for (std::size_t i = 0; i < d.x.size(); ++i) differ += d.x[i] != r.x[i];
  for (std::size_t i = 0; i < d.F.size(); ++i) {
    differ += d.F[i] != r.F[i];
    strain = std::max(strain, std::fabs(d.F[i] - ((i % 9) % 4 == 0 ? 1.0 : 0.0)));
  }
  Gathered rest;
  elastogen::Simulation still(MPI_COMM_SELF, cfg);
  still.splats()->gather(still.dynamics().x().data(), rest.x, rest.F);
  for (std::size_t i = 0; i < d.x.size(); ++i)
    moved = std::max(moved, std::fabs(d.x[i] - rest.x[i]));
  EXPECT_EQ(differ, 0);
  // The scene really deforms: the splats move and strain.
  EXPECT_GT(moved, 1e-4);
  EXPECT_GT(strain, 1e-4);
}

TEST(ElastogenSplats, RigidRotationGivesTheRotationAsGradient) {
  // The ball alone turns on a kinematic path about an oblique axis; a separate free cube keeps
  // the system's unknowns non-empty and stays at rest (no gravity, no load).
  const std::string dir = scratch_dir("elastogen_splats_rigid");
  Config cfg = ball_deck(dir, 2000);
  cfg.gravity = {0.0, 0.0, 0.0};
  cfg.forces.clear();
  cfg.fixed.clear();
  cfg.geometry[0].lo = {0.26, 0.02, 0.02};
  cfg.geometry[0].hi = {0.3, 0.06, 0.06};
  KinematicConfig kin;
  kin.region.lo = {0.0, -1.0, -1.0};
  kin.region.hi = {0.2, 1.0, 1.0};
  kin.center = {0.12, 0.05, 0.05};
  const double w = 2.0, axis[3] = {1 / std::sqrt(3.0), -1 / std::sqrt(3.0), 1 / std::sqrt(3.0)};
  kin.angular_velocity = {w * axis[0], w * axis[1], w * axis[2]};
  cfg.kinematic.push_back(kin);
  const int steps = 5;
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
  for (int s = 0; s < steps; ++s) sim.dynamics().step(s * cfg.dt);
  const Gathered g = gather_splats(sim);
  const elastogen::DeckObject obj = elastogen::build_deck_object(cfg);
  if (test::world_rank() != 0) return;
  // Rodrigues rotation by w t about the axis.
  const double th = w * steps * cfg.dt, c = std::cos(th), s = std::sin(th);
  double R[9];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const double cross = (i == j) ? 0.0 : (((j - i + 3) % 3 == 1) ? -1 : 1) * axis[3 - i - j];
      R[3 * i + j] = (i == j ? c : 0.0) + s * cross + (1 - c) * axis[i] * axis[j];
    }
  const std::size_t n = obj.splats.size(), ball_first = n - 2000;
  ASSERT_EQ(g.x.size(), 3 * n);
  double worst_F = 0, worst_x = 0, still_F = 0;
  for (std::size_t i = ball_first; i < n; ++i) {
    const double* p = &obj.splats.position[3 * i];
    for (int r = 0; r < 3; ++r) {
      double q = kin.center[r];
      for (int a = 0; a < 3; ++a) q += R[3 * r + a] * (p[a] - kin.center[a]);
      worst_x = std::max(worst_x, std::fabs(g.x[3 * i + r] - q));
      for (int a = 0; a < 3; ++a)
        worst_F = std::max(worst_F, std::fabs(g.F[9 * i + 3 * r + a] - R[3 * r + a]));
    }
  }
  for (std::size_t i = 0; i < ball_first; ++i)
    for (int e = 0; e < 9; ++e)
      still_F = std::max(still_F, std::fabs(g.F[9 * i + e] - (e % 4 == 0 ? 1.0 : 0.0)));
  // Every node of the ball's voxels is prescribed: exact up to rounding.
  EXPECT_LT(worst_F, 1e-12);
  EXPECT_LT(worst_x, 1e-12);
  EXPECT_GT(th, 0.09);  // a real rotation (0.1 rad)
  EXPECT_LT(still_F, 1e-9);
}

TEST(ElastogenSplats, AffineNodeMotionIsReproducedExactly) {
  // A sphere part beside the splat ball: its lattice splats include some in voxels the
  // centre-sampled voxelization left empty, which extrapolate their nearest solid voxel.
  const std::string dir = scratch_dir("elastogen_splats_affine");
  Config cfg = ball_deck(dir, 2000);
  cfg.geometry[0].type = "sphere";
  cfg.geometry[0].center = {0.05, 0.05, 0.05};
  cfg.geometry[0].radius = 0.041;
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
  const elastogen::SplatEmbedding* s = sim.splats();
  ASSERT_NE(s, nullptr);
  EXPECT_GT(s->extrapolated(), 0);
  const double A[9] = {1.1, 0.2, -0.1, 0.05, 0.9, 0.3, -0.2, 0.1, 1.2};
  const double b[3] = {0.3, -0.1, 0.05};
  auto affine = [&](const std::array<double, 3>& p) {
    std::array<double, 3> q{};
    for (int r = 0; r < 3; ++r)
      q[r] = A[3 * r] * p[0] + A[3 * r + 1] * p[1] + A[3 * r + 2] * p[2] + b[r];
    return q;
  };
  Gathered g;
  s->gather(node_field(sim.system(), affine).data(), g.x, g.F);
  const elastogen::DeckObject obj = elastogen::build_deck_object(cfg);
  if (test::world_rank() != 0) return;
  ASSERT_EQ(g.x.size(), 3 * obj.splats.size());
  double worst_F = 0, worst_x = 0;
  for (std::size_t i = 0; i < obj.splats.size(); ++i) {
    const auto q = affine({obj.splats.position[3 * i], obj.splats.position[3 * i + 1],
                           obj.splats.position[3 * i + 2]});
    for (int r = 0; r < 3; ++r) worst_x = std::max(worst_x, std::fabs(g.x[3 * i + r] - q[r]));
    for (int e = 0; e < 9; ++e) worst_F = std::max(worst_F, std::fabs(g.F[9 * i + e] - A[e]));
  }
  EXPECT_LT(worst_F, 1e-12);
  EXPECT_LT(worst_x, 1e-14);
}

TEST(ElastogenSplats, RunRendersFramesIdenticalAtAnyRankCount) {
  const std::string dir = scratch_dir("elastogen_splats_render");
  Config cfg = ball_deck(dir, 2000);
  cfg.render.enabled = true;
  cfg.render.width = 64;
  cfg.render.height = 48;
  cfg.render.center = {0.1, 0.05, 0.05};
  cfg.render.radius = 0.5;
  cfg.render.azimuth = 30;
  cfg.render.d_azimuth = 10;
  cfg.render.mp4 = true;
  cfg.output.frame_interval = 0.01;
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
  const std::string out = dir + "/dist";
  ASSERT_EQ(sim.run(out, false).exit_code, 0);
  if (test::world_rank() != 0) return;
  // Frames 0..3 (rest and 3 steps).
  for (long f = 0; f < 4; ++f) {
    const std::string name = fmt::format("/png/frame_{:06d}.png", f);
    const auto pic = test::load_png(out + name);
    ASSERT_EQ(pic.width, 64) << name;
    ASSERT_EQ(pic.height, 48);
    long drawn = 0;
    for (int y = 0; y < pic.height; ++y)
      for (int x = 0; x < pic.width; ++x)
        drawn += pic.at(x, y) != std::array<std::uint8_t, 3>{255, 255, 255};
    EXPECT_GT(drawn, 100) << name;  // the object covers part of the white background
  }
  EXPECT_FALSE(fs::exists(out + "/png/frame_000004.png"));
  if (!gaussians::find_ffmpeg().empty()) EXPECT_GT(fs::file_size(out + "/render.mp4"), 0u);
  elastogen::Simulation serial(MPI_COMM_SELF, cfg);
  const std::string ref = dir + "/serial";
  ASSERT_EQ(serial.run(ref, false).exit_code, 0);
  for (long f = 0; f < 4; ++f) {
    const std::string name = fmt::format("/png/frame_{:06d}.png", f);
    EXPECT_EQ(bytes_of(out + name), bytes_of(ref + name)) << name;
  }
  EXPECT_NE(bytes_of(out + "/png/frame_000000.png"), bytes_of(out + "/png/frame_000003.png"));
}

TEST(ElastogenSplats, RestartRebuildsTheSplatsAndContinuesTheImages) {
  const std::string dir = scratch_dir("elastogen_splats_restart");
  Config cfg = ball_deck(
      dir, 1000,
      {"simulation.end_time=0.06", "output.checkpoint_every=2", "output.checkpoint_keep=5"});
  cfg.render.enabled = true;
  cfg.render.width = 32;
  cfg.render.height = 24;
  cfg.render.center = {0.1, 0.05, 0.05};
  cfg.render.radius = 0.5;
  const std::string out = dir + "/out";
  {
    elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
    ASSERT_EQ(sim.run(out, false).exit_code, 0);
  }
  const auto past = fs::file_time_type::clock::now() - std::chrono::hours(24);
  std::vector<std::string> original;
  auto png = [&](long f) { return out + fmt::format("/png/frame_{:06d}.png", f); };
  if (test::world_rank() == 0) {
    for (long f = 0; f < 7; ++f) {
      original.push_back(bytes_of(png(f)));
      ASSERT_FALSE(original.back().empty()) << f;
      fs::last_write_time(png(f), past);
    }
    std::ofstream(png(99)) << "stale";  // an image the restart must drop
  }
  MPI_Barrier(MPI_COMM_WORLD);
  {
    elastogen::Simulation resumed(MPI_COMM_WORLD, cfg);
    resumed.load_checkpoint(io::checkpoint_path(out, 2));
    ASSERT_EQ(resumed.run(out, true).exit_code, 0);
  }
  if (test::world_rank() != 0) return;
  for (long f = 0; f < 7; ++f) {
    // Same rank count: the continued images are bit-identical to the first run's.
    EXPECT_EQ(bytes_of(png(f)), original[f]) << f;
    // Images up to the restart step (0, 1, 2) are kept, later ones rewritten.
    EXPECT_EQ(fs::last_write_time(png(f)) == past, f <= 2) << f;
  }
  EXPECT_FALSE(fs::exists(png(99)));
}

TEST(ElastogenSplats, TrainedDonutRidesTheVoxels) {
  const std::string ply = std::string(GEN4D_SHARED_DIR) + "/data/splats/donut/point_cloud.ply";
  if (!fs::exists(ply)) GTEST_SKIP() << ply << " is not available";
  Config cfg = parse_deck(kDeck, "<donut>", ".", {"domain.voxel_size=0.01"});
  cfg.forces.clear();
  cfg.fixed.front().region = {{-1, -1, -1}, {1, 1, 0.03}};
  GeometryConfig g;
  g.type = "splats";
  g.file = ply;
  cfg.geometry = {g};
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
  const elastogen::SplatEmbedding* s = sim.splats();
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->count(), static_cast<long>(gaussians::load_geometry_splats(g).size()));
  EXPECT_EQ(s->extrapolated(), 0);  // every splat's cell is occupied, hence solid
  for (int k = 0; k < 2; ++k) sim.dynamics().step(k * cfg.dt);
  const Gathered d = gather_splats(sim);
  if (test::world_rank() != 0) return;
  elastogen::Simulation serial(MPI_COMM_SELF, cfg);
  for (int k = 0; k < 2; ++k) serial.dynamics().step(k * cfg.dt);
  const Gathered r = gather_splats(serial);
  EXPECT_TRUE(d.x == r.x);
  EXPECT_TRUE(d.F == r.F);
}
