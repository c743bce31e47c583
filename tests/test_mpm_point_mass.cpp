// [[point_mass]] on MPM particles (an added density): the mass lands on the region's particles in
// proportion to theirs, the same at any rank count; a body with it falls as before but an impulse
// moves it as its total mass predicts, in the MPM solver and in diagnose's MPM forward model.
#include <gtest/gtest.h>
#include <mpi.h>

#include <cmath>
#include <string>
#include <vector>

#include "core/Deck.hpp"
#include "core/Error.hpp"
#include "deck_test_util.hpp"
#include "forward/MpmModel.hpp"
#include "mpm/MpmSimulation.hpp"
#include "mpm_test_util.hpp"

using namespace gen4d;
using test::quoted;
using test::toml;

namespace {

constexpr double kDensity = 1000, kBlockMass = kDensity * 0.08 * 0.04 * 0.04;  // 0.128 kg
constexpr double kPointMass = 0.05, kDt = 1e-3;
const Vec3d kForce{0.5, 0, 0};

//! A block [0, 0.08] x [0, 0.04] x [0, 0.04] on MPM cells of 0.02 m (2 particles per cell and
//! axis, fixed substeps of 1 ms); `gravity`; with a push `kForce` on the whole block for ten
//! substeps (`push`) and kPointMass kg on its half x >= `mass_from` (none for 1).
std::string block_deck(const Vec3d& gravity, bool push, double mass_from) {
  test::TestDeck d;
  d.simulation(kDt, 0.03, {{"gravity", toml(gravity)}})
      .mpm()
      .domain(0.02)
      .table("mpm", {{"lo", toml(Vec3d{-0.1, -0.1, -0.2})},
                     {"hi", toml(Vec3d{0.3, 0.14, 0.14})},
                     {"particles_per_axis", "2"},
                     {"substep", quoted("fixed")}})
      .box({0, 0, 0}, {0.08, 0.04, 0.04})
      .material(2e5, 0.3, kDensity, {{"model", quoted("fixed_corotated")}});
  if (push)
    d.table("[boundary]", {{"type", quoted("particle_impulse")},
                           {"lo", toml(Vec3d{-1, -1, -1})},
                           {"hi", toml(Vec3d{1, 1, 1})},
                           {"force", toml(kForce)},
                           {"start", "0"},
                           {"end", "0.0095"}});  // ten substeps: t = 0 .. 0.009
  if (mass_from < 1)
    d.region("point_mass", {mass_from, -1, -1}, {1, 1, 1}, {{"mass", toml(kPointMass)}});
  return d;
}

Config config(const std::string& text) {
  return parse_deck(text, "block.toml", ".");
}

//! `substeps` fixed substeps of the deck's dt from t = 0.
void advance(mpm::MpmSimulation& sim, int substeps) {
  double t = 0;
  for (int k = 0; k < substeps; ++k, t += kDt) sim.solver().substep(t, kDt);
}

//! Sum over every rank of f(particle i) over the local particles.
template <class F>
double total(const mpm::Particles& p, const F& f) {
  double s = 0;
  for (std::size_t i = 0; i < p.size(); ++i) s += f(i);
  double all = 0;
  MPI_Allreduce(&s, &all, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  return all;
}

TEST(MpmPointMass, LandsOnTheRegionsParticlesByTheirMass) {
  mpm::MpmSimulation sim(MPI_COMM_WORLD, config(block_deck({0, 0, 0}, false, 0.04)));
  const mpm::Particles& p = sim.solver().particles();
  const double n = total(p, [](std::size_t) { return 1.0; });
  ASSERT_EQ(n, 128.0);  // 4 x 2 x 2 cells, 8 particles each
  const double m0 = kBlockMass / n;
  const double heavy = m0 * (1 + kPointMass / (kBlockMass / 2));
  for (std::size_t i = 0; i < p.size(); ++i)
    EXPECT_NEAR(p.mass[i], p.x[3 * i] >= 0.04 ? heavy : m0, 1e-15) << p.id[i];
  EXPECT_NEAR(total(p, [&](std::size_t i) { return p.mass[i]; }), kBlockMass + kPointMass, 1e-15);
  // The same particles at any rank count, bit for bit (rank 0 seeds them alone to compare).
  const std::vector<double> all = test::gather_sorted(MPI_COMM_WORLD, p);
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  if (rank == 0) {
    mpm::MpmSimulation serial(MPI_COMM_SELF, config(block_deck({0, 0, 0}, false, 0.04)));
    EXPECT_EQ(all, test::gather_sorted(MPI_COMM_SELF, serial.solver().particles()));
  }
}

TEST(MpmPointMass, FreeFallIsUnchanged) {
  const Vec3d g{0, 0, -9.81};
  mpm::MpmSimulation plain(MPI_COMM_WORLD, config(block_deck(g, false, 1)));
  mpm::MpmSimulation loaded(MPI_COMM_WORLD, config(block_deck(g, false, 0.04)));
  advance(plain, 20);
  advance(loaded, 20);
  const auto a = test::gather_sorted(MPI_COMM_WORLD, plain.solver().particles());
  const auto b = test::gather_sorted(MPI_COMM_WORLD, loaded.solver().particles());
  ASSERT_EQ(a.size(), b.size());
  const int R = mpm::Particles::kRecord;
  // Records: id, x (3), v (3), ...: every particle where it would be without the mass, and
  // where gravity takes it (symplectic Euler: g dt^2 n (n + 1) / 2 after n substeps), to the
  // rounding of the transfers (1e-10 of the speed).
  const double drop = -9.81 * kDt * kDt * 20 * 21 / 2, speed = 9.81 * kDt * 20;
  for (std::size_t r = 0; r < a.size() / R; ++r) {
    for (int k = 1; k < 4; ++k) EXPECT_NEAR(a[r * R + k], b[r * R + k], 1e-13) << r;
    for (int k = 4; k < 7; ++k) EXPECT_NEAR(a[r * R + k], b[r * R + k], 1e-10 * speed) << r;
    EXPECT_NEAR(b[r * R + 6], -speed, 1e-10 * speed) << r;
  }
  if (!a.empty()) {
    mpm::MpmSimulation rest(MPI_COMM_SELF, config(block_deck({0, 0, 0}, false, 1)));
    const auto z0 = test::gather_sorted(MPI_COMM_SELF, rest.solver().particles());
    for (std::size_t r = 0; r < a.size() / R; ++r)
      EXPECT_NEAR(b[r * R + 3] - z0[r * R + 3], drop, 1e-12) << r;
  }
}

TEST(MpmPointMass, AnImpulseMovesTheTotalMass) {
  // kForce for 10 ms on the whole block: the momentum F T is the same, the velocity is F T over
  // the total mass, with the point mass on half of the body.
  const double impulse = kForce[0] * 10 * kDt;
  for (const double mass_from : {1.0, 0.04}) {
    mpm::MpmSimulation sim(MPI_COMM_WORLD, config(block_deck({0, 0, 0}, true, mass_from)));
    advance(sim, 15);
    const mpm::Particles& p = sim.solver().particles();
    const double mass = kBlockMass + (mass_from < 1 ? kPointMass : 0.0);
    const double n = total(p, [](std::size_t) { return 1.0; });
    const double momentum = total(p, [&](std::size_t i) { return p.mass[i] * p.v[3 * i]; });
    const double mean_v = total(p, [&](std::size_t i) { return p.v[3 * i]; }) / n;
    EXPECT_NEAR(momentum, impulse, 1e-10 * impulse) << mass_from;
    EXPECT_NEAR(mean_v, impulse / mass, 1e-10 * impulse / mass) << mass_from;
    for (std::size_t i = 0; i < p.size(); ++i)
      ASSERT_NEAR(p.v[3 * i], impulse / mass, 1e-10 * impulse / mass) << "a rigid translation";
  }
}

TEST(MpmPointMass, ARegionWithoutParticlesIsRefused) {
  // Beyond the block; a slab 0.038 <= z <= 0.04 under its top face (the voxels' nodes lie on
  // the face, the particles a quarter cell inside).
  std::string face = block_deck({0, 0, 0}, false, 1);
  face += "\n[[point_mass]]\nlo = [0, 0, 0.038]\nhi = [0.08, 0.04, 0.04]\nmass = 0.005\n";
  for (const std::string& text : {block_deck({0, 0, 0}, false, 0.5), face}) {
    const Config cfg = config(text);
    ASSERT_EQ(cfg.point_masses.size(), 1u);
    const std::string where = cfg.point_masses[0].where;
    EXPECT_NE(where.find("block.toml:"), std::string::npos) << where;
    for (int model = 0; model < 2; ++model) {
      try {
        if (model == 0) {
          mpm::MpmSimulation sim(MPI_COMM_WORLD, cfg);
        } else {
          forward::MpmModel m(cfg);
        }
        ADD_FAILURE() << "an empty [[point_mass]] region was accepted: " << where;
      } catch (const InputError& e) {
        const std::string msg = e.what();
        EXPECT_NE(msg.find(where + ":"), std::string::npos) << msg;
        if (model == 0 || text == face)
          EXPECT_NE(msg.find("holds no MPM particle"), std::string::npos) << msg;
      }
    }
  }
}

TEST(MpmPointMass, TheForwardModelCarriesIt) {
  // diagnose's MPM model: a marker at the block's centre moves, after the push, by F T / M per
  // second: with the point mass by kBlockMass / (kBlockMass + kPointMass) of the plain run's.
  std::vector<double> moved;
  for (const double mass_from : {1.0, 0.04}) {
    const forward::MpmModel m(config(block_deck({0, 0, 0}, true, mass_from)));
    forward::ChannelRequest r;
    r.at = m.attach({0.04, 0.02, 0.02});
    r.t = {0.0, 0.02};
    const forward::Trace tr = m.run(m.nominal(), {r});
    ASSERT_TRUE(tr.ok) << tr.failure;
    moved.push_back(tr.channel[0][3] - tr.channel[0][0]);
  }
  EXPECT_GT(moved[0], 0);
  EXPECT_NEAR(moved[1] / moved[0], kBlockMass / (kBlockMass + kPointMass), 1e-9);
}

}  // namespace
