// ElastoGen and the Newton reference on cells with a spacing per axis, point masses and
// pre-loads: a cubic deck given as [h, h, h] against h, a thin cantilever on cells twice as
// long as they are thick against Euler-Bernoulli, a point mass's weight, a pluck released
// from its static deflection, a point mass that misses the object, and the bits across ranks.
//
// The strip: 0.3 x 0.02 x 0.02 m, clamped at x = 0, E = 1 MPa, nu = 0, rho = 1000 kg/m^3,
// cells [2 hz, hz, hz]; a 1 mN tip load bends it by F L^3 / (3 E I) = 0.675 mm (0.2 % of L,
// so the corotated solution is the linear one).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "core/Error.hpp"
#include "materials/Arap.hpp"
#include "elastogen_test_util.hpp"

using namespace gen4d;

namespace {

constexpr double kL = 0.3, kW = 0.02, kT = 0.02, kE = 1e6, kRho = 1000, kF = 1e-3;

//! The Euler-Bernoulli tip deflection of the strip under a tip load F.
double euler_bernoulli(double F, double E = kE) {
  const double I = kW * kT * kT * kT / 12.0;
  return F * kL * kL * kL / (3.0 * E * I);
}

struct Strip {
  std::string voxel = "[0.02, 0.01, 0.01]";  //!< domain.voxel_size as written
  double dt = 1e-3, end_time = 1.0, gravity = 0, E = kE;
  std::string method = "elastogen";
  std::string solver;  //!< more [solver] keys
  std::string more;    //!< more tables
};

std::string strip_deck(const Strip& s) {
  return fmt::format(R"(
[simulation]
name = "strip"
dt = {dt}
end_time = {end}
gravity = [0.0, 0.0, {g}]

[domain]
voxel_size = {voxel}

[[geometry]]
type = "box"
lo = [0.0, 0.0, 0.0]
hi = [{L}, {W}, {T}]

[material]
model = "fixed_corotated"
target = "analytic"
youngs_modulus = {E}
poisson_ratio = 0.0
density = {rho}

[solver]
method = "{method}"
{solver}

[[fixed]]
lo = [-1.0, -1.0, -1.0]
hi = [1e-4, 1.0, 1.0]
{more}
)",
                     fmt::arg("dt", s.dt), fmt::arg("end", s.end_time), fmt::arg("g", s.gravity),
                     fmt::arg("voxel", s.voxel), fmt::arg("L", kL), fmt::arg("W", kW),
                     fmt::arg("T", kT), fmt::arg("E", s.E), fmt::arg("rho", kRho),
                     fmt::arg("method", s.method), fmt::arg("solver", s.solver),
                     fmt::arg("more", s.more));
}

//! A [[force]] of `fz` newtons along z on the tip face, over [start, end).
std::string tip_force(double fz, double start, double end) {
  return fmt::format(R"(
[[force]]
lo = [{lo}, -1.0, -1.0]
hi = [1.0, 1.0, 1.0]
force = [0.0, 0.0, {fz}]
start = {start}
end = {end}
)",
                     fmt::arg("lo", kL - 1e-4), fmt::arg("fz", fz), fmt::arg("start", start),
                     fmt::arg("end", end));
}

Config parse(const Strip& s) {
  return parse_deck(strip_deck(s), "<strip>", ".");
}

//! Mean z displacement of the tip face's nodes (x = L), on every rank.
double tip_z(elastogen::Simulation& sim) {
  const auto x = test::gather_positions(sim);
  double z = 0;
  if (test::world_rank() == 0) {
    const auto& d = sim.grid().global_nodes();
    const auto& o = sim.system().origin();
    const Vec3d& h = sim.spacing();
    int n = 0;
    for (long k = 0; k < d[2]; ++k)
      for (long j = 0; j < d[1]; ++j)
        for (long i = 0; i < d[0]; ++i) {
          const double X = o[0] + h[0] * i, Y = o[1] + h[1] * j, Z = o[2] + h[2] * k;
          if (std::fabs(X - kL) > 1e-9 || Y < -1e-9 || Y > kW + 1e-9 || Z < -1e-9 || Z > kT + 1e-9)
            continue;
          z += x[3 * ((k * d[1] + j) * d[0] + i) + 2] - Z;
          ++n;
        }
    z /= n;
  }
  MPI_Bcast(&z, 1, MPI_DOUBLE, 0, MPI_COMM_WORLD);
  return z;
}

//! The static tip deflection (down, > 0) under the tip load, through the pre-load's solve.
double static_deflection(const std::string& voxel, elastogen::PreloadStats* stats = nullptr) {
  Strip s;
  s.voxel = voxel;
  s.more = tip_force(-kF, -1, 1e300);
  elastogen::Simulation sim(MPI_COMM_WORLD, parse(s));
  const auto st = sim.dynamics().settle_preloads();
  if (stats) *stats = st;
  return -tip_z(sim);
}

}  // namespace

TEST(ElastogenCells, CubicDeckAsThreeEdgesIsBitIdentical) {
  Strip a, b;
  a.voxel = "0.01";
  b.voxel = "[0.01, 0.01, 0.01]";
  a.gravity = b.gravity = -9.81;
  a.more = b.more = tip_force(-0.05, 0, 0.004);
  const Config ca = parse(a), cb = parse(b);
  EXPECT_EQ(ca.spacing, cb.spacing);
  elastogen::Simulation sa(MPI_COMM_WORLD, ca), sb(MPI_COMM_WORLD, cb);
  EXPECT_TRUE(sb.system().cubic());
  for (int s = 0; s < 6; ++s) {
    sa.dynamics().step(s * ca.dt);
    sb.dynamics().step(s * cb.dt);
  }
  const auto xa = test::gather_positions(sa), xb = test::gather_positions(sb);
  const auto va = test::gather_positions(sa, true), vb = test::gather_positions(sb, true);
  if (test::world_rank() == 0) {
    ASSERT_EQ(xa.size(), xb.size());
    long differ = 0;
    double moved = 0;
    for (std::size_t i = 0; i < xa.size(); ++i) {
      differ += xa[i] != xb[i] || va[i] != vb[i];
      moved = std::max(moved, std::fabs(va[i]));
    }
    EXPECT_EQ(differ, 0);
    EXPECT_GT(moved, 1e-3);
  }
}

TEST(ElastogenCells, GlobalStepOperatorIsTheCellsLaplacian) {
  // d^T (k L) d from the fused stencil (interior rows of eight coefficient classes, general
  // rows elsewhere) against sum over cells and Gauss points of k w |grad d|^2, the gradient
  // taken per axis by the local step's kernel: the same quadratic form, to rounding.
  Strip s;
  s.voxel = "[0.02, 0.01, 0.005]";
  elastogen::Simulation sim(MPI_COMM_WORLD, parse(s));
  const elastogen::VoxelSystem& sys = sim.system();
  ASSERT_FALSE(sys.cubic());
  const auto& G = sys.ghosted();
  const auto& free = sys.free_mask();
  std::vector<double> d(3 * G.size(), 0.0), out(3 * G.size(), 0.0);
  for (long k = G.start[2]; k < G.start[2] + G.count[2]; ++k)
    for (long j = G.start[1]; j < G.start[1] + G.count[1]; ++j)
      for (long i = G.start[0]; i < G.start[0] + G.count[0]; ++i) {
        const std::size_t n = G.index(i, j, k);
        for (int c = 0; c < 3; ++c)
          d[3 * n + c] = free[n] ? std::sin(1.3 * i + 0.7 * j * j + 2.1 * k + c) : 0.0;
      }
  const double stiffness = 3.0e5;
  sys.apply(stiffness, 0.0, d.data(), out.data());
  double form = 0, cells = 0;
  long interior = 0;
  elastogen::for_owned(sys.owned(), G, [&](std::size_t n, long, long, long) {
    interior += sys.adjacency()[n] == 0xFF && free[n];
    for (int c = 0; c < 3; ++c) form += d[3 * n + c] * out[3 * n + c];
  });
  const Vec3d& h = sys.spacing();
  const double inv_h[3] = {1 / h[0], 1 / h[1], 1 / h[2]}, w = h[0] * h[1] * h[2] / 8;
  const auto& oc = sys.grid().owned_cells();
  for (long ck = oc.start[2]; ck < oc.start[2] + oc.count[2]; ++ck)
    for (long cj = oc.start[1]; cj < oc.start[1] + oc.count[1]; ++cj)
      for (long ci = oc.start[0]; ci < oc.start[0] + oc.count[0]; ++ci) {
        if (!sys.solid(ci, cj, ck)) continue;
        double de[8][3], F[8][9];
        for (int m = 0; m < 8; ++m)
          for (int c = 0; c < 3; ++c)
            de[m][c] = d[3 * G.index(ci + (m & 1), cj + (m >> 1 & 1), ck + (m >> 2 & 1)) + c];
        elastogen::HexGauss::gradients(de, inv_h, F);
        for (int q = 0; q < 8; ++q)
          for (int e = 0; e < 9; ++e) cells += stiffness * w * F[q][e] * F[q][e];
      }
  MPI_Allreduce(MPI_IN_PLACE, &form, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  MPI_Allreduce(MPI_IN_PLACE, &cells, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  MPI_Allreduce(MPI_IN_PLACE, &interior, 1, MPI_LONG, MPI_SUM, MPI_COMM_WORLD);
  EXPECT_GT(interior, 0);  // the interior stencil took part
  EXPECT_NEAR(form, cells, 1e-12 * cells);
}

TEST(ElastogenCells, AffineMotionGivesItsGradientOnBoxCells) {
  // Patch test: nodes moved by x = A X give F = A at every Gauss point of every cell, so the
  // elastic energy is the solid volume times psi(A), whatever the cell's edges.
  Strip s;
  s.voxel = "[0.02, 0.01, 0.005]";
  elastogen::Simulation sim(MPI_COMM_WORLD, parse(s));
  elastogen::VoxelSystem& sys = sim.system();
  const double A[9] = {1.01, 0.02, -0.01, 0.015, 0.98, 0.03, -0.02, 0.01, 1.03};
  const auto x = test::node_field(sys, [&](const std::array<double, 3>& X) {
    return std::array<double, 3>{A[0] * X[0] + A[1] * X[1] + A[2] * X[2],
                                 A[3] * X[0] + A[4] * X[1] + A[5] * X[2],
                                 A[6] * X[0] + A[7] * X[1] + A[8] * X[2]};
  });
  std::vector<double> f(x.size());
  const elastogen::ArapPolarStress law{materials::Arap::from_young_poisson(kE, 0.3)};
  double energy = sys.internal_forces(law, x.data(), f.data()).value();
  MPI_Allreduce(MPI_IN_PLACE, &energy, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  double P[9];
  const double psi = law(A, P);
  const Vec3d& h = sys.spacing();
  const double volume = sys.global_solid_cells() * h[0] * h[1] * h[2];
  EXPECT_NEAR(volume, kL * kW * kT, 1e-12);
  EXPECT_NEAR(energy, volume * psi, 1e-9 * volume * psi);
}

TEST(ElastogenCells, ThinCantileverConvergesTowardsEulerBernoulli) {
  // Cells twice as long as thick, refined once: the trilinear voxel (full 2x2x2 rule) locks
  // in bending, more so on elongated cells, so it is stiff on coarse cells and closes in on
  // beam theory as hz falls: -33.2 % at hz = T/2, -10.9 % at T/4, -2.8 % at T/8 (not run
  // here: 60 x 8 x 8 cells take a minute).
  const double eb = euler_bernoulli(kF);
  elastogen::PreloadStats st1, st2;
  const double d1 = static_deflection("[0.02, 0.01, 0.01]", &st1);    // hz = T/2
  const double d2 = static_deflection("[0.01, 0.005, 0.005]", &st2);  // hz = T/4
  const double e1 = (d1 - eb) / eb, e2 = (d2 - eb) / eb;
  if (test::world_rank() == 0)
    std::printf(
        "[thin cantilever] Euler-Bernoulli %.4e m; hz = T/2: %.4e m (%+.1f %%, %ld CG), "
        "T/4: %.4e m (%+.1f %%, %ld CG)\n",
        eb, d1, 100 * e1, st1.cg_iterations, d2, 100 * e2, st2.cg_iterations);
  for (const auto* st : {&st1, &st2}) EXPECT_LT(st->relative_residual, 1e-6);
  // Stiff (locking) at both levels, and the error falls by more than half.
  EXPECT_LT(e1, 0);
  EXPECT_LT(e2, 0);
  EXPECT_LT(-e2, 0.5 * -e1);
  EXPECT_LT(-e2, 0.15);
}

TEST(ElastogenCells, NewtonAgreesWithTheStaticSolveAndWithElastogen) {
  // The Newton reference's static step (dt = 1e4 s: no inertia) from rest, its tangent
  // assembled per axis, against the pre-load's matrix-free static solve.
  const double settled = static_deflection("[0.02, 0.01, 0.01]");
  Strip n;
  n.method = "newton";
  n.dt = n.end_time = 1e4;
  n.solver = "relaxation = \"cg\"";
  n.more = tip_force(-kF, 0, 1e300);
  elastogen::Simulation sn(MPI_COMM_WORLD, parse(n));
  const auto st = sn.dynamics().step(0.0);
  const double newton = -tip_z(sn);
  if (test::world_rank() == 0)
    std::printf("[thin cantilever] static: pre-load solve %.8e m, Newton step %.8e m (%d its)\n",
                settled, newton, st.outer);
  EXPECT_TRUE(st.accurate);
  EXPECT_LT(std::fabs(newton - settled), 1e-6 * settled);

  // Dynamics: ElastoGen's stencils per axis against Newton, five steps under a tip load.
  Strip d;
  d.dt = 0.01;
  d.solver = "accuracy_tolerance = 1e-8\nmax_extra_outer = 3000";
  d.more = tip_force(-0.05, 0, 1e300);
  Strip dn = d;
  dn.method = "newton";
  elastogen::Simulation e(MPI_COMM_WORLD, parse(d)), nn(MPI_COMM_WORLD, parse(dn));
  for (int s = 0; s < 5; ++s) {
    ASSERT_TRUE(e.dynamics().step(s * d.dt).accurate) << "elastogen step " << s;
    ASSERT_TRUE(nn.dynamics().step(s * d.dt).accurate) << "newton step " << s;
  }
  const auto xe = test::gather_positions(e), xn = test::gather_positions(nn);
  const auto ve = test::gather_positions(e, true);
  if (test::world_rank() == 0) {
    const auto [diff, motion] = test::agreement(xe, xn, ve, 5 * d.dt);
    std::printf("[thin cantilever] elastogen vs newton: max difference %.3e m, motion %.3e m\n",
                diff, motion);
    EXPECT_GT(motion, 1e-4);
    EXPECT_LT(diff, 1e-5 * motion);
  }
}

TEST(ElastogenCells, PointMassWeighsOnTheTip) {
  // Under gravity, a 5 g point mass on the tip face sags the strip (E = 100 MPa here) as a
  // tip load of its weight does on the bare strip (same nodes, shared by mass alike): to the
  // solver's tolerance. The extra sag is below m g L^3 / (3 E I) by the voxel's locking.
  const double m = 0.005, g = 9.81;
  const std::string voxel = "[0.02, 0.01, 0.01]";
  const std::string tip = fmt::format("lo = [{}, -1.0, -1.0]\nhi = [1.0, 1.0, 1.0]\n", kL - 1e-4);
  Strip bare;
  bare.voxel = voxel;
  bare.gravity = -g;
  bare.E = 1e8;
  Strip with_mass = bare;
  with_mass.more = "[[point_mass]]\n" + tip + fmt::format("mass = {}\n", m);
  Strip with_load = bare;
  with_load.more = tip_force(-m * g, -1, 1e300);
  elastogen::Simulation s0(MPI_COMM_WORLD, parse(bare)), s1(MPI_COMM_WORLD, parse(with_mass)),
      s2(MPI_COMM_WORLD, parse(with_load));
  // The lumped masses gain exactly m (to rounding).
  double added = 0, body = 0;
  {
    const auto& m0 = s0.system().mass();
    const auto& m1 = s1.system().mass();
    elastogen::for_owned(s1.system().owned(), s1.system().ghosted(),
                         [&](std::size_t n, long, long, long) {
                           added += m1[n] - m0[n];
                           body += m0[n];
                         });
    MPI_Allreduce(MPI_IN_PLACE, &added, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
    MPI_Allreduce(MPI_IN_PLACE, &body, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  }
  EXPECT_NEAR(added, m, 1e-12);
  EXPECT_NEAR(body, kRho * kL * kW * kT, 1e-12);
  s0.dynamics().settle_preloads();
  s1.dynamics().settle_preloads();
  s2.dynamics().settle_preloads();
  const double z0 = tip_z(s0), z1 = tip_z(s1), z2 = tip_z(s2);
  const double extra = z0 - z1, expected = euler_bernoulli(m * g, bare.E);
  if (test::world_rank() == 0)
    std::printf(
        "[point mass] sag %.6e m bare, %.6e m with 5 g, %.6e m with its weight as a load; "
        "extra %.4e m, beam theory %.4e m\n",
        -z0, -z1, -z2, extra, expected);
  EXPECT_LT(std::fabs(z1 - z2), 1e-7 * std::fabs(z1));
  EXPECT_GT(extra, 0.6 * expected);
  EXPECT_LT(extra, expected);
}

TEST(ElastogenCells, PluckStartsFromTheStaticDeflectionAndSwingsAboutRest) {
  // A pluck: the tip load is a pre-load released at t = 0. Frame 0 is its static deflection
  // (run() settles it before the first frame); the strip then swings through rest to the
  // other side and back, about z = 0. f1 = 1.14 Hz; dt = T1 / 50.
  const double settled = static_deflection("[0.02, 0.01, 0.01]");
  Strip s;
  s.dt = 0.0176;
  s.end_time = s.dt;
  s.more = tip_force(-kF, -1, 0);
  const Config cfg = parse(s);
  {
    elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
    sim.run(test::scratch_dir("elastogen_cells_pluck"), false);
    // One step after the release the tip has barely moved off the static deflection.
    const double z = tip_z(sim);
    EXPECT_LT(std::fabs(-z - settled), 0.1 * settled);
    EXPECT_LT(-z, settled);  // unloaded, it starts to rise
  }
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
  sim.prepare_start();
  const double z0 = tip_z(sim);
  EXPECT_NEAR(-z0, settled, 1e-10 * settled);
  std::vector<double> z;
  for (int k = 0; k < 50; ++k) {
    sim.dynamics().step(k * s.dt);
    z.push_back(tip_z(sim));
  }
  double lo = 0, hi = 0, mean = 0;
  for (double v : z) {
    lo = std::min(lo, v);
    hi = std::max(hi, v);
    mean += v / z.size();
  }
  if (test::world_rank() == 0)
    std::printf(
        "[pluck] frame 0 tip %.4e m (static %.4e m); over one period: %.4e .. %.4e m, "
        "mean %.2e m\n",
        z0, -settled, lo, hi, mean);
  EXPECT_GT(hi, 0.5 * settled);               // swings through rest to the other side
  EXPECT_LT(std::fabs(mean), 0.2 * settled);  // about rest, not about the deflection
  EXPECT_LT(z.back(), 0);                     // and back down after a period
}

TEST(ElastogenCells, PointMassOutsideTheObjectIsAnInputError) {
  Strip s;
  s.more = "\n[[point_mass]]\nlo = [0.5, 0.5, 0.5]\nhi = [0.6, 0.6, 0.6]\nmass = 0.01\n";
  const Config cfg = parse(s);
  try {
    elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
    FAIL() << "a point mass on no node was accepted";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(cfg.point_masses.at(0).where), std::string::npos) << msg;
    EXPECT_NE(msg.find("[[point_mass]]"), std::string::npos) << msg;
    EXPECT_NE(msg.find("no node"), std::string::npos) << msg;
  }
}

TEST(ElastogenCells, ThinCellsPointMassAndPluckAreBitIdenticalAcrossRankCounts) {
  Strip s;
  s.voxel = "[0.01, 0.005, 0.005]";
  s.dt = 0.005;
  s.gravity = -9.81;
  s.more = tip_force(-0.02, -1, 0) +
           fmt::format(
               "\n[[attached_mass]]\nlo = [{}, -1.0, -1.0]\nhi = [1.0, 1.0, 1.0]\n"
               "mass = 0.002\n",
               kL - 0.02);
  const Config cfg = parse(s);
  const int steps = 5;
  elastogen::Simulation dist(MPI_COMM_WORLD, cfg);
  dist.prepare_start();
  for (int k = 0; k < steps; ++k) dist.dynamics().step(k * cfg.dt);
  const auto xd = test::gather_positions(dist), vd = test::gather_positions(dist, true);
  if (test::world_rank() == 0) {
    elastogen::Simulation serial(MPI_COMM_SELF, cfg);
    serial.prepare_start();
    for (int k = 0; k < steps; ++k) serial.dynamics().step(k * cfg.dt);
    const auto xs = test::gather_positions(serial), vs = test::gather_positions(serial, true);
    ASSERT_EQ(xs.size(), xd.size());
    long differ = 0;
    double moved = 0;
    for (std::size_t i = 0; i < xs.size(); ++i) {
      differ += xs[i] != xd[i] || vs[i] != vd[i];
      moved = std::max(moved, std::fabs(vs[i]));
    }
    EXPECT_EQ(differ, 0);
    EXPECT_GT(moved, 1e-3);
  }
}
