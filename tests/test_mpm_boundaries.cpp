// MPM boundary conditions and damping after PhysGaussian: the moving cuboid and its reset, the
// "cut" collider, RPIC / PIC transfers, grid velocity damping, their deck keys and errors, and
// rank-count bit-identity with all of them on.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "core/Deck.hpp"
#include "core/Error.hpp"
#include "geometry/Shape.hpp"
#include "mpm/MpmSimulation.hpp"
#include "mpm/Seeding.hpp"
#include "mpm/Solver.hpp"
#include "deck_test_util.hpp"
#include "mpm_test_util.hpp"

namespace gen4d {
namespace {

using test::gather_sorted;
using test::grid;
using test::jelly;

int world_rank() {
  int r = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &r);
  return r;
}

struct Scene {
  std::vector<BoundaryConfig> bcs;
  Vec3d velocity{0, 0, 0};
  Vec3d gravity{0, 0, 0};
  double rpic = 0;
  double grid_scale = 1;
  bool adaptive = true;
  double max_dt = 2e-3;
};

//! The block [0, 0.3] x [0, 0.2] x [0, 0.35] (2 particles per cell and axis) under `s`.
std::unique_ptr<mpm::Solver> make(MPI_Comm comm, const Scene& s) {
  mpm::SolverOptions opt = test::options(s.gravity, s.max_dt, s.adaptive);
  opt.rpic_damping = s.rpic;
  opt.grid_velocity_scale = s.grid_scale;
  return test::block_solver(comm, jelly(), opt, s.bcs, s.velocity);
}

//! Substeps from t until t reaches `until` exactly (the last substep is shortened).
void run_until(mpm::Solver& s, double& t, double until) {
  while (t < until) {
    const double dt = s.stable_dt(until - t);
    s.substep(t, dt);
    t = dt == until - t ? until : t + dt;
  }
}

// Record layout (Particles::pack): id, x (3), v (3), C (9), ...
constexpr int kX = 1, kV = 4;

//! Whether the 3x3x3 stencil of a particle at x (nodes within 1.5 dx) lies inside `box`.
bool stencil_inside(const double* x, const BoxRegion& box, double dx) {
  for (int d = 0; d < 3; ++d)
    if (x[d] - 1.5 * dx < box.lo[d] || x[d] + 1.5 * dx > box.hi[d]) return false;
  return true;
}

BoundaryConfig pusher(const std::string& motion) {
  BoundaryConfig b;
  b.type = "cuboid";
  b.region = {{-0.1, -0.1, -0.1}, {0.1, 0.3, 0.45}};  // the block's left third, all y and z
  b.velocity = {0.5, 0, 0};
  b.motion = motion;
  b.end = 0.2;
  return b;
}

TEST(MpmBoundaries, CuboidRegionMovesWithItsVelocityWhileActive) {
  BoundaryConfig b = pusher("moving");
  b.start = 0.1;
  b.end = 0.3;
  const auto at = [&](double t) { return mpm::cuboid_region(b, t); };
  EXPECT_EQ(at(0.05).lo[0], -0.1);  // before start: where lo / hi put it
  EXPECT_DOUBLE_EQ(at(0.2).lo[0], -0.1 + 0.5 * 0.1);
  EXPECT_DOUBLE_EQ(at(0.2).hi[0], 0.1 + 0.5 * 0.1);
  EXPECT_NEAR(at(0.3).lo[0], -0.1 + 0.5 * 0.2, 1e-15);
  EXPECT_EQ(at(7.0).lo[0], at(0.3).lo[0]);  // after end it stays
  EXPECT_EQ(at(0.2).lo[1], -0.1);
  EXPECT_EQ(at(0.2).hi[2], 0.45);
  b.motion = "fixed";
  EXPECT_EQ(at(0.2).lo[0], -0.1);
}

TEST(MpmBoundaries, MovingCuboidCarriesTheMaterialInsideIt) {
  // The cuboid moves 0.1 m in 0.2 s; the particles whose stencils stay inside it ride along
  // at exactly its velocity, and it pushes the rest of the block ahead of it.
  const double T = 0.2, dx = grid().dx;
  const Vec3d v = {0.5, 0, 0};
  const BoundaryConfig moving = pusher("moving");
  double t = 0;
  auto s = make(MPI_COMM_WORLD, {{moving}});
  const auto before = gather_sorted(MPI_COMM_WORLD, s->particles());
  run_until(*s, t, T);
  const auto after = gather_sorted(MPI_COMM_WORLD, s->particles());
  // The same with the box fixed at lo / hi.
  double tf = 0;
  auto f = make(MPI_COMM_WORLD, {{pusher("fixed")}});
  run_until(*f, tf, T);
  const auto fixed = gather_sorted(MPI_COMM_WORLD, f->particles());
  if (world_rank() != 0) return;
  const int R = mpm::Particles::kRecord;
  ASSERT_EQ(before.size(), after.size());
  const BoxRegion start_box = moving.region, end_box = mpm::cuboid_region(moving, T);
  EXPECT_DOUBLE_EQ(end_box.hi[0], 0.2);
  long riders = 0, pushed = 0, fixed_riders = 0;
  double worst = 0;
  for (std::size_t i = 0; i < before.size(); i += R) {
    const double* x0 = &before[i + kX];
    const double* x1 = &after[i + kX];
    if (stencil_inside(x0, start_box, dx) && stencil_inside(x1, end_box, dx)) {
      ++riders;
      for (int d = 0; d < 3; ++d) {
        worst = std::max(worst, std::abs(x1[d] - x0[d] - v[d] * T));
        worst = std::max(worst, std::abs(after[i + kV + d] - v[d]));
      }
      fixed_riders += std::abs(fixed[i + kX] - x0[0] - v[0] * T) < 1e-3;
    }
    if (x0[0] > 0.2) pushed += x1[0] - x0[0] > 0.02;  // ahead of the box, moved by it
  }
  EXPECT_GT(riders, 40);
  EXPECT_LT(worst, 1e-10);
  EXPECT_GT(pushed, 100);
  // A fixed box lets its material leave it: none of those particles travelled v T.
  EXPECT_EQ(fixed_riders, 0);
}

TEST(MpmBoundaries, CuboidResetStopsEveryGridVelocityAfterEnd) {
  // The cuboid pushes for 0.05 s; then the scene is zeroed for reset_duration.
  BoundaryConfig b = pusher("moving");
  b.end = 0.05;
  b.reset_duration = 0.01;
  Scene with{{b}};
  with.adaptive = false;
  with.max_dt = 1e-3;
  double t = 0;
  auto s = make(MPI_COMM_WORLD, with);
  run_until(*s, t, b.end);
  EXPECT_GT(s->kinetic_energy(), 1e-4);
  s->substep(t, 1e-3);  // t = end: inside the window
  t += 1e-3;
  EXPECT_EQ(s->kinetic_energy(), 0.0);
  // Particles keep still while the window lasts, whatever their stresses.
  const auto x_a = gather_sorted(MPI_COMM_WORLD, s->particles());
  run_until(*s, t, b.end + 0.009);
  EXPECT_EQ(s->kinetic_energy(), 0.0);
  const auto x_b = gather_sorted(MPI_COMM_WORLD, s->particles());
  if (world_rank() == 0) {
    ASSERT_EQ(x_a.size(), x_b.size());
    for (std::size_t i = 0; i < x_a.size(); ++i) EXPECT_EQ(x_a[i], x_b[i]) << i;
  }
  // After it, the stressed block moves again.
  run_until(*s, t, b.end + 0.02);
  EXPECT_GT(s->kinetic_energy(), 0.0);
  // Without the reset the block keeps its motion.
  b.reset_duration = 0;
  Scene without{{b}};
  without.adaptive = false;
  without.max_dt = 1e-3;
  double t2 = 0;
  auto u = make(MPI_COMM_WORLD, without);
  run_until(*u, t2, b.end + 1e-3);
  EXPECT_GT(u->kinetic_energy(), 1e-4);
}

TEST(MpmBoundaries, CutColliderStopsAllButTheCutWhereItSlidesDamped) {
  // Plane z = 0.2 (allowed side above) with the cut x >= 0.15; the block moves at v.
  BoundaryConfig cut = mpm::surface_collider("cut", {0, 0, 0.2}, {0, 0, 1});
  cut.region = {{0.15, -1, -1}, {1, 1, 1}};
  cut.cut_scale = 0.3;
  const Vec3d v = {0.3, 0.2, -1};
  Scene sc{{cut}, v};
  sc.adaptive = false;
  sc.max_dt = 1e-4;
  auto s = make(MPI_COMM_WORLD, sc);
  const auto before = gather_sorted(MPI_COMM_WORLD, s->particles());
  s->substep(0, 1e-4);
  const auto after = gather_sorted(MPI_COMM_WORLD, s->particles());
  if (world_rank() != 0) return;
  const double dx = grid().dx;
  const BoxRegion behind = {{-1, -1, -1}, {1, 1, 0.2}}, ahead = {{-1, -1, 0.2}, {1, 1, 1}};
  const BoxRegion in_cut = {{0.15, -1, -1}, {1, 1, 0.2}};
  const Vec3d slide = {0.3 * v[0], 0.3 * v[1], 0};  // normal part removed, the rest x 0.3
  long n_cut = 0, n_stop = 0, n_free = 0;
  double worst = 0;
  const int R = mpm::Particles::kRecord;
  for (std::size_t i = 0; i < before.size(); i += R) {
    const double* x = &before[i + kX];
    const double* u = &after[i + kV];
    const Vec3d* want = nullptr;
    static const Vec3d zero = {0, 0, 0};
    if (stencil_inside(x, in_cut, dx)) {
      want = &slide;
      ++n_cut;
    } else if (stencil_inside(x, behind, dx) && x[0] + 1.5 * dx < 0.15) {
      want = &zero;
      ++n_stop;
    } else if (stencil_inside(x, ahead, dx)) {
      want = &v;
      ++n_free;
    }
    if (want)
      for (int d = 0; d < 3; ++d) worst = std::max(worst, std::abs(u[d] - (*want)[d]));
  }
  EXPECT_GT(n_cut, 10);
  EXPECT_GT(n_free, 10);
  EXPECT_GT(n_stop, 10);
  EXPECT_LT(worst, 1e-10);
}

//! One particle at x0 with velocity v0 and affine matrix C0, one substep without gravity:
//! its new C is the transferred matrix (quadratic B-splines reproduce it exactly).
std::array<double, 9> transferred_C(double rpic, const double* C0) {
  mpm::SolverOptions opt;
  opt.gravity = {0, 0, 0};
  opt.max_dt = 1e-4;
  opt.adaptive = false;
  opt.rpic_damping = rpic;
  auto m = jelly();
  mpm::Solver s(MPI_COMM_WORLD, grid(), m, opt, {});
  mpm::Particles p;
  if (world_rank() == 0) {
    const double x0[3] = {0.21, 0.13, 0.07}, v0[3] = {0.1, -0.05, 0.2};
    double state[mpm::kStateSize];
    m->init_state(state);
    p.push_back(0, x0, v0, 1e-3, 1e-6, state);
    std::copy_n(C0, 9, p.C.data());
  }
  s.distribute(std::move(p));
  s.substep(0, 1e-4);
  std::array<double, 9> C{};
  if (s.particles().size() == 1) std::copy_n(s.particles().C.data(), 9, C.data());
  MPI_Allreduce(MPI_IN_PLACE, C.data(), 9, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  return C;
}

TEST(MpmBoundaries, RpicDampingBlendsTheAffineMatrixTowardsItsSkewPart) {
  const double C0[9] = {0.1, 0.5, -0.2, 0.3, -0.4, 0.6, 0.7, 0.2, 0.05};
  for (const double r : {0.0, 0.5, 1.0, -1.0}) {
    const auto C = transferred_C(r, C0);
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) {
        const double skew = 0.5 * (C0[3 * a + b] - C0[3 * b + a]);
        const double want = r < 0 ? 0.0 : (1 - r) * C0[3 * a + b] + r * skew;
        EXPECT_NEAR(C[3 * a + b], want, 1e-9) << "r " << r << " (" << a << ", " << b << ")";
      }
  }
}

TEST(MpmBoundaries, GridVelocityScaleDampsFreeFlightByItsFactorPerSubstep) {
  // A block in uniform motion under gravity: each substep v <- s (v + g dt).
  const double s = 0.97, dt = 1e-3;
  Scene sc{{}, {0.3, -0.2, 0.5}, {0, 0, -9.81}, 0, s, false, dt};
  auto solver = make(MPI_COMM_WORLD, sc);
  const double M = solver->total_mass();
  Vec3d want = sc.velocity;
  double t = 0;
  for (int k = 0; k < 20; ++k) {
    solver->substep(t, dt);
    t += dt;
    for (int d = 0; d < 3; ++d) want[d] = s * (want[d] + sc.gravity[d] * dt);
  }
  const auto P = solver->total_momentum();
  for (int d = 0; d < 3; ++d) EXPECT_NEAR(P[d] / M, want[d], 1e-10) << d;
  EXPECT_LT(want[0], 0.3 * 0.6);  // 0.97^20 = 0.54: the damping is really on
}

TEST(MpmBoundaries, BitIdenticalAcrossRankCountsWithEveryOption) {
  BoundaryConfig push = pusher("moving");
  push.end = 0.03;
  push.reset_duration = 0.004;
  BoundaryConfig cut = mpm::surface_collider("cut", {0, 0, 0.05}, {0, 0.6, 0.8});
  cut.region = {{0.05, -1, -1}, {0.2, 1, 1}};
  cut.cut_scale = 0.4;
  const Scene sc{{push, cut}, {0.1, 0.2, -0.5}, {0, 0, -9.81}, 0.4, 0.999};
  double t = 0;
  auto dist = make(MPI_COMM_WORLD, sc);
  run_until(*dist, t, 0.05);
  const auto a = gather_sorted(MPI_COMM_WORLD, dist->particles());
  if (world_rank() != 0) return;
  double ts = 0;
  auto serial = make(MPI_COMM_SELF, sc);
  run_until(*serial, ts, 0.05);
  const auto b = gather_sorted(MPI_COMM_SELF, serial->particles());
  ASSERT_EQ(a.size(), b.size());
  ASSERT_GT(a.size(), 0u);
  const auto [differ, moved] = test::compare_runs(a, b);
  EXPECT_EQ(differ, 0);
  EXPECT_GT(moved, 1e-2);
}

// ---- deck keys ----

const std::string kDeck =
    test::TestDeck()
        .simulation(1e-3, 0.01, {test::TestDeck::no_gravity()})
        .mpm()
        .domain(0.05)
        .box({0, 0, 0}, {0.2, 0.2, 0.2})
        .material(1e5, 0.3, 1000, {{"model", test::quoted("fixed_corotated")}})
        .table("mpm", {{"rpic_damping", "0.5"}, {"grid_velocity_scale", "0.9995"}})
        .region("boundary", {0, 0, 0}, {0.1, 0.2, 0.05},
                {{"type", test::quoted("cuboid")},
                 {"velocity", "[0.1, 0, 0]"},
                 {"motion", test::quoted("moving")},
                 {"reset_duration", "0.002"},
                 {"end", "0.005"}})
        .table("[boundary]", {{"type", test::quoted("surface_collider")},
                              {"point", "[0, 0, 0.1]"},
                              {"normal", "[0, 1, 0]"},
                              {"surface", test::quoted("cut")},
                              {"lo", "[0, 0, 0.04]"},
                              {"hi", "[1, 1, 0.053]"},
                              {"cut_scale", "0.25"}});

//! The message of the InputError that parsing `text` as "bc.toml" throws ("" if none).
std::string deck_error(const std::string& text) {
  try {
    parse_deck(text, "bc.toml", ".", {});
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

std::string replace(std::string text, const std::string& from, const std::string& to) {
  const auto pos = text.find(from);
  EXPECT_NE(pos, std::string::npos) << from;
  if (pos != std::string::npos) text.replace(pos, from.size(), to);
  return text;
}

int line_of(const std::string& text, const std::string& needle) {
  const auto pos = text.find(needle);
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + pos, '\n'));
}

TEST(MpmBoundaryDeck, KeysReachTheConfigAndTheSolver) {
  const Config c = parse_deck(kDeck, "bc.toml", ".", {});
  EXPECT_EQ(c.mpm.rpic_damping, 0.5);
  EXPECT_EQ(c.mpm.grid_velocity_scale, 0.9995);
  ASSERT_EQ(c.boundaries.size(), 2u);
  EXPECT_EQ(c.boundaries[0].motion, "moving");
  EXPECT_EQ(c.boundaries[0].reset_duration, 0.002);
  EXPECT_EQ(c.boundaries[1].surface, "cut");
  EXPECT_EQ(c.boundaries[1].region.lo[2], 0.04);
  EXPECT_EQ(c.boundaries[1].region.hi[2], 0.053);
  EXPECT_EQ(c.boundaries[1].cut_scale, 0.25);
  // Defaults: APIC, no grid damping, a fixed cuboid without reset, cut_scale 0.3.
  const Config d = parse_deck(replace(replace(replace(replace(kDeck, "rpic_damping = 0.5\n", ""),
                                                      "grid_velocity_scale = 0.9995\n", ""),
                                              "motion = \"moving\"\nreset_duration = 0.002\n", ""),
                                      "cut_scale = 0.25\n", ""),
                              "bc.toml", ".", {});
  EXPECT_EQ(d.mpm.rpic_damping, 0);
  EXPECT_EQ(d.mpm.grid_velocity_scale, 1);
  EXPECT_EQ(d.boundaries[0].motion, "fixed");
  EXPECT_EQ(d.boundaries[0].reset_duration, 0);
  EXPECT_EQ(d.boundaries[1].cut_scale, 0.3);
  // The run's solver takes the [mpm] values.
  mpm::MpmSimulation sim(MPI_COMM_WORLD, c);
  EXPECT_EQ(sim.solver().options().rpic_damping, 0.5);
  EXPECT_EQ(sim.solver().options().grid_velocity_scale, 0.9995);
  EXPECT_EQ(sim.solver().options().damping, 0);
}

TEST(MpmBoundaryDeck, BadValuesNameFileLineAndKey) {
  struct Case {
    std::string from, to, key, detail;
    std::string at = "";  //!< text of the line the error names; "" for `to`'s line
  };
  const std::vector<Case> cases = {
      {"rpic_damping = 0.5", "rpic_damping = 1.5", "mpm.rpic_damping", "or -1 for PIC"},
      {"rpic_damping = 0.5", "rpic_damping = -0.5", "mpm.rpic_damping", "or -1 for PIC"},
      {"grid_velocity_scale = 0.9995", "grid_velocity_scale = 0", "mpm.grid_velocity_scale",
       "must be in (0, 1]"},
      {"grid_velocity_scale = 0.9995", "grid_velocity_scale = 1.1", "mpm.grid_velocity_scale",
       "must be in (0, 1]"},
      {"motion = \"moving\"", "motion = \"sliding\"", "boundary.0.motion", "moving"},
      {"reset_duration = 0.002", "reset_duration = -1", "boundary.0.reset_duration", ">= 0"},
      {"end = 0.005\n", "\n", "boundary.0.reset_duration", "needs an end"},
      {"cut_scale = 0.25", "cut_scale = 2", "boundary.1.cut_scale", "must be in [0, 1]"},
      {"surface = \"cut\"", "surface = \"slip\"", "boundary.1.lo", "only applies to surface",
       "lo = [0, 0, 0.04]"},
      {"surface = \"cut\"", "surface = \"knife\"", "boundary.1.surface", "cut"},
  };
  for (const Case& c : cases) {
    const std::string text = replace(kDeck, c.from, c.to);
    const std::string msg = deck_error(text);
    SCOPED_TRACE(c.to + " -> " + msg);
    ASSERT_FALSE(msg.empty());
    EXPECT_EQ(msg.find('\n'), std::string::npos);
    EXPECT_NE(msg.find("'" + c.key + "'"), std::string::npos);
    EXPECT_NE(msg.find(c.detail), std::string::npos);
    if (c.from != "end = 0.005\n")
      EXPECT_NE(msg.find("bc.toml:" + std::to_string(line_of(text, c.at.empty() ? c.to : c.at))),
                std::string::npos);
  }
  // A cut without its box; motion on a type that has none.
  const std::string no_box = replace(kDeck, "lo = [0, 0, 0.04]\n", "");
  EXPECT_NE(deck_error(no_box).find("boundary.1.lo"), std::string::npos) << deck_error(no_box);
  const std::string foreign = replace(kDeck, "cut_scale = 0.25", "motion = \"moving\"");
  EXPECT_NE(deck_error(foreign).find("boundary.1.motion"), std::string::npos)
      << deck_error(foreign);
}

}  // namespace
}  // namespace gen4d
