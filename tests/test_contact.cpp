// Static colliders with Coulomb friction ([[collider]]) and surface tractions ([[traction]]).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "deck_test_util.hpp"
#include "elastogen_test_util.hpp"

using namespace gen4d;

namespace {

//! A w x w x hgt block of side voxels h (padding 0: every grid node is an object node).
std::string block_deck(double w, double hgt, double z0, double h, double dt, double end_time) {
  return test::TestDeck()
      .simulation(dt, end_time, {{"gravity", "[0, 0, -9.81]"}})
      .unpadded(h)
      .box({0, 0, z0}, {w, w, z0 + hgt})
      .material(1.0e5, 0.0, 1000);
}

Config deck(const std::string& text, const std::vector<std::string>& sets) {
  return parse_deck(text, "<contact>", ".", sets);
}

double min_component(const std::vector<double>& f, int c) {
  double lo = 1e300;
  for (std::size_t i = c; i < f.size(); i += 3) lo = std::min(lo, f[i]);
  return lo;
}

double max_abs(const std::vector<double>& f) {
  double hi = 0;
  for (double v : f) hi = std::max(hi, std::fabs(v));
  return hi;
}

//! Mass-weighted means over the object and its lowest point, on every rank.
struct Motion {
  double x = 0, vx = 0, vz = 0, zmin = 0;
};
Motion motion(elastogen::Simulation& sim) {
  const auto& O = sim.grid().owned_nodes();
  const auto& G = sim.grid().ghosted_nodes();
  const auto& m = sim.system().mass();
  const auto &x = sim.dynamics().x(), &v = sim.dynamics().v();
  double s[4] = {0, 0, 0, 0}, zmin = 1e300;
  for (long k = O.start[2]; k < O.start[2] + O.count[2]; ++k)
    for (long j = O.start[1]; j < O.start[1] + O.count[1]; ++j)
      for (long i = O.start[0]; i < O.start[0] + O.count[0]; ++i) {
        const std::size_t n = G.index(i, j, k);
        if (m[n] == 0) continue;
        s[0] += m[n] * x[3 * n];
        s[1] += m[n] * v[3 * n];
        s[2] += m[n] * v[3 * n + 2];
        s[3] += m[n];
        zmin = std::min(zmin, x[3 * n + 2]);
      }
  MPI_Allreduce(MPI_IN_PLACE, s, 4, MPI_DOUBLE, MPI_SUM, sim.grid().comm());
  MPI_Allreduce(MPI_IN_PLACE, &zmin, 1, MPI_DOUBLE, MPI_MIN, sim.grid().comm());
  return {s[0] / s[3], s[1] / s[3], s[2] / s[3], zmin};
}

//! Gives every node of the object the velocity v.
void set_velocity(elastogen::Simulation& sim, const Vec3d& v) {
  auto& vel = sim.dynamics().v();
  for (std::size_t n = 0; n < vel.size() / 3; ++n)
    for (int d = 0; d < 3; ++d) vel[3 * n + d] = sim.system().mass()[n] > 0 ? v[d] : 0.0;
  sim.dynamics().sync_ghosts();
}

const char* kGround = R"(
[[collider]]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
)";

}  // namespace

TEST(Contact, DroppedBlockComesToRestOnTheGround) {
  // A 0.1 m cube (h = 0.02, nu = 0) dropped from 5 cm. Nodes are pushed out at the end of every
  // step, so none may end a step below the plane. At rest, the column is the 1D chain: the top
  // sinks by rho g H^2 / (2 E) (exact for lumped masses), plus the scheme's support offset:
  // contact nodes (mass m_c) carry the whole weight M g by sinking M g dt^2 / m_c during each
  // step's solve, which lowers everything above by that much (M / m_c = 10 here).
  const double W = 0.1, H = 0.04, h = 0.02, dt = 0.002, E = 1e5, rho = 1000, g = 9.81;
  const Config cfg = deck(block_deck(W, H, 0.01, h, dt, 0.6) + kGround, {});
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
  const int steps = 200;
  double deepest_end = 0, deepest_solve = 0, last_solve = 0;
  long touched = 0;
  for (int s = 0; s < steps; ++s) {
    const auto st = sim.dynamics().step(s * dt);
    deepest_solve = std::max(deepest_solve, st.penetration);
    touched = std::max(touched, st.contacts);
    last_solve = st.penetration;
    deepest_end = std::max(deepest_end, -motion(sim).zmin);
  }
  const Motion end = motion(sim);
  const auto x = test::gather_positions(sim), v = test::gather_positions(sim, true);
  if (test::world_rank() != 0) return;
  const auto& dims = sim.grid().global_nodes();
  // Top layer's mean height.
  double top = 0;
  const long layer = dims[0] * dims[1];
  for (long p = layer * (dims[2] - 1); p < layer * dims[2]; ++p) top += x[3 * p + 2];
  top /= static_cast<double>(layer);
  const double sag = rho * g * H * H / (2 * E), offset = 4 * g * dt * dt;
  const double expected = H - sag - offset;
  std::printf(
      "[ drop ] deepest end-of-step penetration %.2e m, deepest in-solve penetration %.2e m, "
      "%ld contact nodes, top %.7f m (expected %.7f = H - sag %.3e - offset %.3e; "
      "difference %.1e m), final in-solve penetration %.4e m, max |v| %.2e m/s\n",
      deepest_end, deepest_solve, touched, top, expected, sag, offset, top - expected, last_solve,
      max_abs(v));
  EXPECT_LE(deepest_end, 1e-15);
  EXPECT_GT(deepest_solve, 0.0);  // it did land
  EXPECT_EQ(touched, dims[0] * dims[1]);
  EXPECT_LT(max_abs(v), 1e-4);
  EXPECT_NEAR(min_component(x, 2), 0.0, 1e-15);
  EXPECT_NEAR(top, expected, 0.02 * (sag + offset));
  EXPECT_NEAR(last_solve, offset, 0.01 * offset);
  EXPECT_NEAR(end.x, W / 2, 1e-9);  // symmetric landing: no drift
}

TEST(Contact, SlidingDistanceMatchesCoulomb) {
  // A slab resting on the plane, launched along x at v0 = 1 m/s, mu = 0.5: it must stop after
  // v0^2 / (2 mu g). Stiff enough (E = 1e6 Pa, h = 0.02 m, dt = 2 ms) that the implicit step
  // damps its vibrations within a few steps, so the normal impulse per step is the weight's,
  // M g dt, and Coulomb removes mu M g dt of momentum per step. Implicit Euler then slides
  // v0 dt / 2 short (it moves each step with the end-of-step velocity: sum of v0 - k mu g dt),
  // 1 % here; beyond that, the contact nodes stick once the slab is slower than
  // mu (M / m_c) g dt ~ 0.04 m/s (the last ~0.2 mm), and the slab settles by ~0.2 mm.
  // So: 3 % against Coulomb, 0.3 % against Coulomb with the implicit-Euler shift (measured
  // -1.02 % and -0.05 %).
  const double mu = 0.5, v0 = 1.0, g = 9.81, dt = 0.002;
  const int steps = 150;
  const Config cfg = deck(block_deck(0.1, 0.04, 0.0, 0.02, dt, steps * dt) + kGround,
                          {"material.youngs_modulus=1e6", "collider.0.friction=0.5"});
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
  set_velocity(sim, {v0, 0, 0});
  const Motion start = motion(sim);
  double stop_time = -1;
  for (int s = 0; s < steps; ++s) {
    sim.dynamics().step(s * dt);
    const Motion m = motion(sim);
    if (stop_time < 0 && m.vx < 0.01 * v0) stop_time = (s + 1) * dt;
  }
  const Motion end = motion(sim);
  if (test::world_rank() != 0) return;
  const double expected = v0 * v0 / (2 * mu * g), slid = end.x - start.x;
  const double discrete = expected - v0 * dt / 2;
  std::printf(
      "[ slide mu = %.2f ] distance %.5f m, Coulomb v0^2/(2 mu g) = %.5f m (%+.2f %%), minus "
      "v0 dt / 2: %.5f m (%+.2f %%), stopped "
      "(mean vx < 0.01 v0) after %.3f s (Coulomb %.3f s), mean vx at %.2f s %.1e m/s\n",
      mu, slid, expected, 100 * (slid - expected) / expected, discrete,
      100 * (slid - discrete) / expected, stop_time, v0 / (mu * g), steps * dt, end.vx);
  EXPECT_NEAR(slid, expected, 0.03 * expected);
  EXPECT_NEAR(slid, discrete, 0.003 * expected);
  EXPECT_NEAR(stop_time, v0 / (mu * g), 0.03 * v0 / (mu * g));
  // Once stuck, what is left is an elastic wobble of the slab on its stuck base, decaying.
  EXPECT_LT(std::fabs(end.vx), 2e-3 * v0);
  EXPECT_GE(end.zmin, 0.0);
}

TEST(Contact, FrictionlessSlidingKeepsItsMomentum) {
  // mu = 0: push-outs are purely normal, so nothing changes the momentum along the plane
  // but the implicit solve's residual (accuracy 1e-3 relative, default).
  const double v0 = 1.0, dt = 0.002;
  const Config cfg = deck(block_deck(0.1, 0.04, 0.0, 0.02, dt, 0.1) + kGround,
                          {"material.youngs_modulus=1e6", "collider.0.friction=0"});
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
  set_velocity(sim, {v0, 0, 0});
  long contacts = 0;
  for (int s = 0; s < 50; ++s) contacts = std::max(contacts, sim.dynamics().step(s * dt).contacts);
  const Motion end = motion(sim);
  if (test::world_rank() != 0) return;
  std::printf("[ slide mu = 0 ] mean vx %.15f m/s after 0.1 s (v0 = %.1f), moved %.5f m\n", end.vx,
              v0, end.x - 0.05);
  EXPECT_GT(contacts, 0);
  EXPECT_NEAR(end.vx, v0, 1e-9);
  EXPECT_NEAR(end.x - 0.05, v0 * 0.1, 1e-9);
}

TEST(Contact, BoxColliderStopsAFallingBlockOnItsTopFace) {
  // A table top: the box reaches up to z = 0.02 and is wider than the block above it.
  const double dt = 0.002, top = 0.02;
  const std::string table = R"(
[[collider]]
type = "box"
lo = [-0.05, -0.05, -1.0]
hi = [0.15, 0.15, 0.02]
friction = 0.3
)";
  const Config cfg = deck(block_deck(0.1, 0.04, 0.03, 0.02, dt, 0.4) + table, {});
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
  double lowest = 1e300, deepest = 0;
  for (int s = 0; s < 150; ++s) {
    deepest = std::max(deepest, sim.dynamics().step(s * dt).penetration);
    const Motion m = motion(sim);
    if (test::world_rank() == 0) lowest = std::min(lowest, m.zmin);
  }
  const auto v = test::gather_positions(sim, true);
  const Motion end = motion(sim);
  if (test::world_rank() != 0) return;
  std::printf(
      "[ box ] lowest node ever %.17g m (top face %.2f m), deepest in-solve %.2e m, "
      "max |v| %.1e m/s\n",
      lowest, top, deepest, max_abs(v));
  EXPECT_GT(deepest, 0.0);
  EXPECT_EQ(lowest, top);  // push-outs land exactly on the face
  EXPECT_EQ(end.zmin, top);
  EXPECT_LT(max_abs(v), 1e-4);
  EXPECT_NEAR(end.x, 0.05, 1e-9);
}

namespace {
//! A clamped 0.2 x 0.04 x 0.04 m beam (10 x 2 x 2 voxels), no gravity, tight solves.
std::string beam_deck() {
  return test::TestDeck()
      .simulation(0.01, 0.1, {test::TestDeck::no_gravity()})
      .unpadded(0.02)
      .box({0, 0, 0}, {0.2, 0.04, 0.04})
      .material(1.0e5, 0.3, 1000)
      .table("solver", {{"accuracy_tolerance", "1e-6"}, {"max_extra_outer", "1000"}})
      .clamp();
}

double tip_z(elastogen::Simulation& sim) {
  const auto x = test::gather_positions(sim);
  if (test::world_rank() != 0) return 0;
  const auto& d = sim.grid().global_nodes();
  double s = 0;
  for (long k = 0; k < d[2]; ++k)
    for (long j = 0; j < d[1]; ++j) s += x[3 * ((k * d[1] + j) * d[0] + d[0] - 1) + 2];
  return s / static_cast<double>(d[1] * d[2]) - 0.02;  // mean minus the rest height
}
}  // namespace

TEST(Traction, TotalForceIsTractionTimesArea) {
  // Top face of a 0.1 x 0.1 x 0.04 block: 25 faces of 0.02^2, 0.01 m^2.
  const std::string loads = R"(
[[traction]]
lo = [-1.0, -1.0, 0.035]
hi = [1.0, 1.0, 1.0]
traction = [3.0, -2.0, 5.0]
end = 0.5
[[traction]]
lo = [-1.0, -1.0, -1.0]
hi = [1.0, 1.0, 1.0]
pressure = 7.0
start = 0.5
[[traction]]
lo = [5.0, 5.0, 5.0]
hi = [6.0, 6.0, 6.0]
traction = [1.0, 1.0, 1.0]
)";
  const Config cfg = deck(block_deck(0.1, 0.04, 0.0, 0.02, 0.01, 1.0) + loads, {});
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
  const auto f = sim.dynamics().traction_force(0.0);
  const double A = 0.1 * 0.1;
  if (test::world_rank() == 0)
    std::printf("[ traction ] total %.17g %.17g %.17g N (expected %.17g %.17g %.17g)\n", f[0], f[1],
                f[2], 3 * A, -2 * A, 5 * A);
  EXPECT_NEAR(f[0], 3.0 * A, 1e-15 * A);
  EXPECT_NEAR(f[1], -2.0 * A, 1e-15 * A);
  EXPECT_NEAR(f[2], 5.0 * A, 1e-15 * A);
  // A pressure over the whole closed surface pushes in everywhere and nets exactly nothing.
  const auto p = sim.dynamics().traction_force(0.5);
  EXPECT_EQ(p, (std::array<double, 3>{0.0, 0.0, 0.0}));
  // Pressure only, after the first window: the block is squeezed (volume shrinks, no motion
  // of the centre).
  for (int s = 0; s < 3; ++s) sim.dynamics().step(0.5 + s * 0.01);
  const Motion m = motion(sim);
  const auto xs = test::gather_positions(sim);
  if (test::world_rank() != 0) return;
  const auto& d = sim.grid().global_nodes();
  const double width = xs[3 * (d[0] - 1)] - xs[0];  // first row: x extent
  EXPECT_LT(width, 0.1);
  EXPECT_NEAR(m.x, 0.05, 1e-12);
}

TEST(Traction, PressurePushesAlongTheInwardNormal) {
  // A pressure on the top face of a free block (no gravity) pushes it down: -p A along z.
  const double p = 50.0, A = 0.01, dt = 0.01;
  const std::string load = R"(
[[traction]]
lo = [-1.0, -1.0, 0.035]
hi = [1.0, 1.0, 1.0]
pressure = 50.0
)";
  const Config cfg =
      deck(block_deck(0.1, 0.04, 0.0, 0.02, dt, 1.0) + load, {"simulation.gravity=[0,0,0]"});
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
  const auto f = sim.dynamics().traction_force(0.0);
  EXPECT_EQ(f[0], 0.0);
  EXPECT_EQ(f[1], 0.0);
  EXPECT_NEAR(f[2], -p * A, 1e-15 * p * A);
  for (int s = 0; s < 5; ++s) sim.dynamics().step(s * dt);
  const Motion m = motion(sim);
  if (test::world_rank() != 0) return;
  const double M = 1000.0 * 0.1 * 0.1 * 0.04, vz = -p * A * 5 * dt / M;
  std::printf("[ pressure ] mean vz %.6e m/s after 5 steps (impulse / mass %.6e)\n", m.vz, vz);
  EXPECT_NEAR(m.vz, vz, 1e-3 * std::fabs(vz));
}

TEST(Traction, EndFaceTractionBendsACantileverLikeTheEquivalentForce) {
  // F = 0.2 N down on the free end face (0.04 x 0.04 m), once as a traction of F / A, once as
  // a [[force]] on the end node layer. On that layer the lumped masses are in proportion to the
  // adjoining end faces (1 : 2 : 4 at corners, edges, inside), so the nodal loads agree, and
  // so must the motion (measured: identical to the last bit).
  const std::string traction = test::TestDeck().region("traction", {0.195, -1, -1}, {1, 1, 1},
                                                       {{"traction", "[0, 0, -125]"}});
  const std::string force =
      test::TestDeck().region("force", {0.195, -1, -1}, {1, 1, 1}, {{"force", "[0, 0, -0.2]"}});
  elastogen::Simulation a(MPI_COMM_WORLD, deck(beam_deck() + traction, {})),
      b(MPI_COMM_WORLD, deck(beam_deck() + force, {}));
  for (int s = 0; s < 5; ++s) {
    ASSERT_TRUE(a.dynamics().step(s * 0.01).accurate);
    ASSERT_TRUE(b.dynamics().step(s * 0.01).accurate);
  }
  const double za = tip_z(a), zb = tip_z(b);
  if (test::world_rank() != 0) return;
  std::printf("[ cantilever ] tip deflection: traction %.12e m, force %.12e m (%.1e relative)\n",
              za, zb, std::fabs(za - zb) / std::fabs(zb));
  EXPECT_LT(zb, -1e-4);  // it bends
  EXPECT_NEAR(za, zb, 1e-7 * std::fabs(zb));
}

namespace {
// A slab on a slope (normal (0.2, 0.1, 1), mu = 0.4) with a wall (box, mu = 0.2) downhill,
// pushed towards the wall by a traction on its uphill face. Default subspace start: for an
// unclamped body in free fall its projections cancel to ~1e-31, which the exact global sums
// (parallel::ExactSum) must still reproduce at any rank count.
const std::string kScene = test::TestDeck()
                               .simulation(0.005, 0.15, {{"gravity", "[0, 0, -9.81]"}})
                               .unpadded(0.02)
                               .box({0, 0, 0}, {0.12, 0.08, 0.04})
                               .material(1.0e5, 0.3, 1000)
                               .table("[collider]", {{"type", test::quoted("plane")},
                                                     {"point", "[0, 0, -0.005]"},
                                                     {"normal", "[0.2, 0.1, 1]"},
                                                     {"friction", "0.4"}})
                               .table("[collider]", {{"type", test::quoted("box")},
                                                     {"lo", "[0.13, -1, -1]"},
                                                     {"hi", "[1, 1, 1]"},
                                                     {"friction", "0.2"}})
                               .region("traction", {-1, -1, -1}, {0.005, 1, 1},
                                       {{"traction", "[200, 0, 0]"}, {"end", "0.1"}});
}  // namespace

TEST(Contact, SceneIsBitIdenticalAcrossRankCounts) {
  // Contact and friction read only each node's own x^n and x, and the traction loads are
  // computed by each node's owner from the ghosted occupancy: nothing depends on the ranks.
  const Config cfg = parse_deck(kScene, "<scene>", ".");
  const int steps = 30;
  elastogen::Simulation dist(MPI_COMM_WORLD, cfg);
  long plane_and_wall = 0;
  for (int s = 0; s < steps; ++s) plane_and_wall += dist.dynamics().step(s * cfg.dt).contacts;
  const auto xd = test::gather_positions(dist), vd = test::gather_positions(dist, true);
  if (test::world_rank() != 0) return;
  elastogen::Simulation serial(MPI_COMM_SELF, cfg);
  for (int s = 0; s < steps; ++s) serial.dynamics().step(s * cfg.dt);
  const auto xs = test::gather_positions(serial), vs = test::gather_positions(serial, true);
  ASSERT_EQ(xs.size(), xd.size());
  long differ = 0;
  double xmax = -1e300;
  for (std::size_t i = 0; i < xs.size(); ++i) differ += xs[i] != xd[i] || vs[i] != vd[i];
  for (std::size_t i = 0; i < xs.size(); i += 3) xmax = std::max(xmax, xs[i]);
  std::printf("[ scene ] %ld node contacts over %d steps, front at x = %.17g (wall 0.13)\n",
              plane_and_wall, steps, xmax);
  EXPECT_EQ(differ, 0);
  EXPECT_GT(plane_and_wall, 0);
  EXPECT_EQ(xmax, 0.13);  // the front face rests against the wall
}

TEST(Contact, MatchesTheNewtonReference) {
  // Both solvers end each step with the same push-out; with tight implicit solves their
  // trajectories must agree to a small fraction of the motion.
  const std::vector<std::string> tight = {
      "material.target=analytic", "solver.accuracy_tolerance=1e-8", "solver.max_extra_outer=3000"};
  auto with = [&](const std::string& method) {
    auto sets = tight;
    sets.push_back("solver.method=" + method);
    sets.push_back("collider.0.point=[0,0,-0.0002]");  // touch down after a few steps
    return parse_deck(kScene, "<scene>", ".", sets);
  };
  const Config ce = with("elastogen"), cn = with("newton");
  elastogen::Simulation e(MPI_COMM_WORLD, ce), n(MPI_COMM_WORLD, cn);
  long contacts = 0;
  const int steps = 8;
  for (int s = 0; s < steps; ++s) {
    const auto se = e.dynamics().step(s * ce.dt);
    ASSERT_TRUE(se.accurate) << "elastogen step " << s;
    ASSERT_TRUE(n.dynamics().step(s * cn.dt).accurate) << "newton step " << s;
    contacts += se.contacts;
  }
  const auto xe = test::gather_positions(e), xn = test::gather_positions(n);
  const auto ve = test::gather_positions(e, true);
  if (test::world_rank() != 0) return;
  const auto [diff, motion_scale] = test::agreement(xe, xn, ve, steps * ce.dt);
  std::printf(
      "[ contact elastogen vs newton ] %ld contacts, max difference %.3e m, motion %.3e m\n",
      contacts, diff, motion_scale);
  EXPECT_GT(contacts, 0);
  EXPECT_LT(diff, 1e-5 * motion_scale);
}
