// MPM solver: rank-count bit-identity, conservation, free fall, boundary conditions, particles
// leaving the grid, migration and the instability guard.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <vector>

#include "geometry/Shape.hpp"
#include "mpm/Seeding.hpp"
#include "mpm/Solver.hpp"
#include "parallel/Reduce.hpp"
#include "mpm_test_util.hpp"

namespace gen4d {
namespace {

int world_rank() {
  int r = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &r);
  return r;
}

std::shared_ptr<const mpm::Material> material(const std::string& model,
                                              std::map<std::string, double> extra = {}) {
  mpm::MaterialParams p;
  p.model = model;
  p.values = {{"youngs_modulus", 2e5}, {"poisson_ratio", 0.3}, {"density", 1000}};
  for (const auto& [k, v] : extra) p.values[k] = v;
  p.source = "test";
  return mpm::make_material(p);
}

BoundaryConfig plane(const char* surface, Vec3d point, Vec3d normal, double mu = 0) {
  return mpm::surface_collider(surface, point, normal, mu);
}

struct Scene {
  std::string model;
  std::map<std::string, double> params;
  std::vector<BoundaryConfig> bcs;
  Vec3d velocity{0, 0, 0};
  Vec3d gravity{0, 0, -9.81};
  bool remove = false;
  double max_dt = 2e-3;
  bool adaptive = true;
};

std::unique_ptr<mpm::Solver> make(MPI_Comm comm, const Scene& s) {
  mpm::SolverOptions opt = test::options(s.gravity, s.max_dt, s.adaptive);
  opt.remove_outside = s.remove;
  return test::block_solver(comm, material(s.model, s.params), opt, s.bcs, s.velocity);
}

using test::gather_sorted;
using test::run;

//! The scene on MPI_COMM_WORLD and on MPI_COMM_SELF (rank 0) must agree in every bit.
void expect_bit_identical(const Scene& scene, int substeps) {
  double t = 0;
  auto dist = make(MPI_COMM_WORLD, scene);
  run(*dist, substeps, t);
  const auto a = gather_sorted(MPI_COMM_WORLD, dist->particles());
  if (world_rank() != 0) return;
  double ts = 0;
  auto serial = make(MPI_COMM_SELF, scene);
  run(*serial, substeps, ts);
  const auto b = gather_sorted(MPI_COMM_SELF, serial->particles());
  ASSERT_EQ(a.size(), b.size()) << scene.model;
  ASSERT_GT(a.size(), 0u);
  const auto [differ, moved] = test::compare_runs(a, b);
  EXPECT_EQ(ts, t);
  EXPECT_EQ(differ, 0) << scene.model;
  EXPECT_GT(moved, 1e-2) << scene.model;  // the scene really moves
}

TEST(MpmSolver, BitIdenticalAcrossRankCountsForEveryMaterial) {
  const BoundaryConfig floor = plane("separate", {0, 0, 0}, {0, 0, 1}, 0.4);
  expect_bit_identical({"fixed_corotated", {}, {floor}, {0.3, 0.1, -0.5}}, 40);
  expect_bit_identical({"stvk_hencky", {}, {floor}, {-0.2, 0, -1}}, 40);
  expect_bit_identical({"neo_hookean", {}, {plane("sticky", {0, 0, 0}, {0, 0, 1})}}, 40);
  expect_bit_identical({"drucker_prager", {{"friction_angle", 30}}, {floor}}, 60);
  expect_bit_identical(
      {"von_mises", {{"yield_stress", 2e3}, {"hardening", 1e3}}, {floor}, {0, 0, -2}}, 40);
  expect_bit_identical({"herschel_bulkley", {{"yield_stress", 50}, {"consistency", 1}}, {floor}},
                       60);
  expect_bit_identical(
      {"fracture", {{"fracture_strain", 0.02}, {"failure_strain", 0.05}}, {floor}, {0, 0, -1}}, 40);
}

TEST(MpmSolver, BitIdenticalWithEveryBoundaryCondition) {
  BoundaryConfig cuboid;
  cuboid.type = "cuboid";
  cuboid.region = {{-0.1, -0.1, -0.1}, {0.4, 0.3, 0.06}};
  cuboid.velocity = {0.2, 0, 0};
  cuboid.end = 0.05;
  BoundaryConfig impulse;
  impulse.type = "particle_impulse";
  impulse.region = {{0.2, -1, -1}, {1, 1, 1}};
  impulse.force = {5, 0, 10};
  impulse.end = 0.03;
  BoundaryConfig translate;
  translate.type = "enforce_particle_translation";
  translate.region = {{-1, -1, -1}, {0.06, 1, 1}};
  translate.velocity = {-0.1, 0, 0};
  BoundaryConfig rotate;
  rotate.type = "enforce_particle_velocity_rotation";
  rotate.point = {0.15, 0.1, 0.3};
  rotate.normal = {0, 0, 1};
  rotate.radius = 0.08;
  rotate.half_height = 0.05;
  rotate.angular_velocity = {0, 0, 3};
  BoundaryConfig release;
  release.type = "release_particles_sequentially";
  release.normal = {0, 0, -1};
  release.layers = 4;
  release.start = 0;
  release.end = 0.06;
  const BoundaryConfig floor = plane("slip", {0, 0, 0}, {0, 0, 1});
  expect_bit_identical({"fixed_corotated", {}, {floor, cuboid, impulse, translate, rotate}}, 40);
  expect_bit_identical({"drucker_prager", {{"friction_angle", 35}}, {floor, release}}, 50);
}

TEST(MpmSolver, MomentumAndMassAreConservedWithoutExternalForces) {
  Scene s{"neo_hookean", {}, {}, {0.4, -0.3, 0.2}, {0, 0, 0}};
  auto solver = make(MPI_COMM_WORLD, s);
  // Add a spin so the APIC transfer of angular momentum is exercised.
  auto& p = solver->particles();
  for (std::size_t i = 0; i < p.size(); ++i) {
    p.v[3 * i + 0] += -2.0 * (p.x[3 * i + 1] - 0.1);
    p.v[3 * i + 1] += 2.0 * (p.x[3 * i + 0] - 0.15);
  }
  const auto P0 = solver->total_momentum();
  const double M0 = solver->total_mass();
  double t = 0, worst = 0;
  for (int k = 0; k < 6; ++k) {
    run(*solver, 10, t);
    const auto P = solver->total_momentum();
    for (int d = 0; d < 3; ++d) worst = std::max(worst, std::abs(P[d] - P0[d]) / std::abs(P0[0]));
  }
  EXPECT_LT(worst, 1e-11);
  EXPECT_EQ(solver->total_mass(), M0);
  EXPECT_EQ(solver->clamped() + solver->removed(), 0);
}

TEST(MpmSolver, FreeFallFollowsGravity) {
  Scene s{"fixed_corotated", {}, {}, {0, 0, 0}};
  auto solver = make(MPI_COMM_WORLD, s);
  const auto& p = solver->particles();
  auto mean_z = [&] {
    parallel::ExactSum sum;
    for (std::size_t i = 0; i < p.size(); ++i) sum.add(p.mass[i] * p.x[3 * i + 2]);
    double out = 0;
    parallel::Reducer(MPI_COMM_WORLD).sum(&sum, &out, 1);
    return out / solver->total_mass();
  };
  const double z0 = mean_z();
  double t = 0;
  run(*solver, 30, t);
  const double expected = z0 - 0.5 * 9.81 * t * t;
  // Symplectic Euler: the position lags the exact parabola by g t dt / 2 at most.
  EXPECT_NEAR(mean_z(), expected, 9.81 * t * 2e-3);
  EXPECT_LT(mean_z(), z0 - 0.4 * 9.81 * t * t);
}

TEST(MpmSolver, StickyFloorStopsTheBody) {
  // The block slides at 1 m/s while falling onto a sticky plane 0.1 m below it.
  Scene s{"fixed_corotated", {}, {plane("sticky", {0, 0, -0.1}, {0, 0, 1})}, {1, 0, -1}};
  auto solver = make(MPI_COMM_WORLD, s);
  double t = 0;
  run(*solver, 80, t);
  const auto& p = solver->particles();
  double lowest = 1e9, slide[2] = {0, 0};
  for (std::size_t i = 0; i < p.size(); ++i) {
    lowest = std::min(lowest, p.x[3 * i + 2]);
    if (p.x[3 * i + 2] < -0.1 + 0.03) {
      slide[0] += p.v[3 * i];
      slide[1] += 1;
    }
  }
  MPI_Allreduce(MPI_IN_PLACE, &lowest, 1, MPI_DOUBLE, MPI_MIN, MPI_COMM_WORLD);
  MPI_Allreduce(MPI_IN_PLACE, slide, 2, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  ASSERT_GT(slide[1], 0);                         // the block reached the plane
  EXPECT_GT(lowest, -0.1 - 0.05);                 // within a cell of the plane, never through it
  EXPECT_LT(std::abs(slide[0] / slide[1]), 0.3);  // the contact layer no longer slides
}

TEST(MpmSolver, ParticlesLeavingTheGridAreClampedOrRemovedAndCounted) {
  for (bool remove : {false, true}) {
    // Shot sideways at 6 m/s with no walls in the way: they reach the grid edge.
    Scene s{"fixed_corotated", {}, {}, {6, 0, 0}, {0, 0, 0}};
    s.remove = remove;
    BoundaryConfig box;
    box.type = "bounding_box";
    box.start = 10;  // walls off: only the grid edge stops them
    s.bcs = {box};
    auto solver = make(MPI_COMM_WORLD, s);
    const long long n0 = solver->count();
    double t = 0;
    run(*solver, 200, t);
    if (remove) {
      EXPECT_GT(solver->removed(), 0);
      EXPECT_EQ(solver->count() + solver->removed(), n0);
    } else {
      EXPECT_GT(solver->clamped(), 0);
      EXPECT_EQ(solver->count(), n0);
    }
    const auto& p = solver->particles();
    const auto g = test::grid();
    for (std::size_t i = 0; i < p.size(); ++i)
      for (int a = 0; a < 3; ++a) {
        const double X = (p.x[3 * i + a] - g.lo[a]) / g.dx;
        ASSERT_GE(X, 1.0);
        ASSERT_LT(X, static_cast<double>(g.cells[a] - 1));
      }
  }
}

TEST(MpmSolver, ParticlesLiveOnTheRankOwningTheirNearestNode) {
  Scene s{"neo_hookean", {}, {}, {2, 1, 0.5}, {0, 0, 0}};
  auto solver = make(MPI_COMM_WORLD, s);
  const long long n0 = solver->count();
  double t = 0;
  run(*solver, 40, t);
  EXPECT_EQ(solver->count(), n0);
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  const auto& p = solver->particles();
  for (std::size_t i = 0; i < p.size(); ++i) ASSERT_EQ(solver->owner_of(&p.x[3 * i]), rank);
  if (size > 1) EXPECT_GT(solver->migrated(), 0);
}

TEST(MpmSolver, HugeFixedTimeStepStopsWithAnInstabilityError) {
  Scene s{"fixed_corotated", {}, {plane("separate", {0, 0, 0}, {0, 0, 1})}, {0, 0, -3}};
  s.adaptive = false;
  s.max_dt = 0.05;  // 20x the elastic limit
  auto solver = make(MPI_COMM_WORLD, s);
  double t = 0;
  try {
    for (int k = 0; k < 200; ++k) {
      solver->substep(t, s.max_dt);
      t += s.max_dt;
    }
    FAIL() << "no instability detected";
  } catch (const mpm::InstabilityError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("MPM instability at t ="), std::string::npos) << what;
    EXPECT_NE(what.find("id "), std::string::npos) << what;
  }
}

TEST(MpmSolver, SequentialReleaseHoldsLayersUntilTheirTime) {
  BoundaryConfig release;
  release.type = "release_particles_sequentially";
  release.normal = {0, 0, 1};
  release.layers = 2;
  release.start = 0;
  release.end = 0.2;  // the upper layer is released at t = 0.1
  Scene s{"fixed_corotated", {}, {release}, {0, 0, 0}};
  auto solver = make(MPI_COMM_WORLD, s);
  double t = 0;
  while (t < 0.05) {
    const double dt = solver->stable_dt(1.0);
    solver->substep(t, dt);
    t += dt;
  }
  const auto& p = solver->particles();
  double top_speed = 0, bottom_speed = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const double sp = std::abs(p.v[3 * i + 2]);
    (p.x[3 * i + 2] > 0.2 ? top_speed : bottom_speed) =
        std::max(p.x[3 * i + 2] > 0.2 ? top_speed : bottom_speed, sp);
  }
  MPI_Allreduce(MPI_IN_PLACE, &top_speed, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
  MPI_Allreduce(MPI_IN_PLACE, &bottom_speed, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
  EXPECT_EQ(top_speed, 0.0);
  EXPECT_GT(bottom_speed, 0.1);
}

}  // namespace
}  // namespace gen4d
