//! Helpers shared by the MPM tests.
#pragma once

#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

#include "geometry/Shape.hpp"
#include "mpm/Material.hpp"
#include "mpm/Particles.hpp"
#include "mpm/Seeding.hpp"
#include "mpm/Solver.hpp"

namespace gen4d::test {

//! The MPM tests' elastic material: fixed corotated, E 2e5 Pa, nu 0.3, 1000 kg/m^3.
inline std::shared_ptr<const mpm::Material> jelly() {
  mpm::MaterialParams p;
  p.model = "fixed_corotated";
  p.values = {{"youngs_modulus", 2e5}, {"poisson_ratio", 0.3}, {"density", 1000}};
  p.source = "test";
  return mpm::make_material(p);
}

//! The MPM tests' grid: 20 x 16 x 18 cells of 0.05 m from (-0.3, -0.3, -0.3).
inline mpm::GridSpec grid() {
  mpm::GridSpec g;
  g.dx = 0.05;
  g.lo = {-0.3, -0.3, -0.3};
  g.cells = {20, 16, 18};
  return g;
}

//! Solver options: `gravity`, substeps of at most max_dt, adaptive or fixed.
inline mpm::SolverOptions options(const Vec3d& gravity, double max_dt, bool adaptive) {
  mpm::SolverOptions opt;
  opt.gravity = gravity;
  opt.max_dt = max_dt;
  opt.adaptive = adaptive;
  return opt;
}

//! A solver on grid() of material m under `opt` and `bcs`, seeded (2 particles per cell and axis)
//! with the block [0, 0.3] x [0, 0.2] x [0, top] moving at `velocity`.
inline std::unique_ptr<mpm::Solver> block_solver(MPI_Comm comm,
                                                 const std::shared_ptr<const mpm::Material>& m,
                                                 const mpm::SolverOptions& opt,
                                                 const std::vector<BoundaryConfig>& bcs,
                                                 const Vec3d& velocity, double top = 0.35) {
  auto solver = std::make_unique<mpm::Solver>(comm, grid(), m, opt, bcs);
  const geometry::Box box(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0.3, 0.2, top));
  solver->distribute(mpm::seed_particles(comm, grid(), box, 2, *m, velocity));
  return solver;
}

//! `substeps` adaptive substeps of `s` from time t (advanced).
inline void run(mpm::Solver& s, int substeps, double& t) {
  for (int k = 0; k < substeps; ++k) {
    const double dt = s.stable_dt(1.0);
    s.substep(t, dt);
    t += dt;
  }
}

//! Every particle's record (Particles::pack), sorted by id, on rank 0 of `comm` (empty
//! elsewhere): how the tests compare runs at different rank counts bit for bit.
inline std::vector<double> gather_sorted(MPI_Comm comm, const mpm::Particles& p) {
  int rank = 0, size = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &size);
  const int R = mpm::Particles::kRecord;
  std::vector<double> local(p.size() * R);
  for (std::size_t i = 0; i < p.size(); ++i) p.pack(i, &local[i * R]);
  const int n = static_cast<int>(local.size());
  std::vector<int> counts(size), displs(size);
  MPI_Gather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, comm);
  int total = 0;
  for (int r = 0; r < size; ++r) {
    displs[r] = total;
    total += counts[r];
  }
  std::vector<double> all(rank == 0 ? total : 0);
  MPI_Gatherv(local.data(), n, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE, 0,
              comm);
  if (rank != 0) return {};
  std::vector<std::size_t> order(all.size() / R);
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](auto a, auto b) { return all[a * R] < all[b * R]; });
  std::vector<double> out(all.size());
  for (std::size_t i = 0; i < order.size(); ++i) std::copy_n(&all[order[i] * R], R, &out[i * R]);
  return out;
}

//! Two gathered runs of one scene (gather_sorted): how many values differ, and the largest
//! velocity component in `a` (that the scene really moves).
struct RunComparison {
  long differ = 0;
  double moved = 0;
};
inline RunComparison compare_runs(const std::vector<double>& a, const std::vector<double>& b) {
  RunComparison c;
  const std::size_t R = mpm::Particles::kRecord;
  for (std::size_t i = 0; i < a.size(); ++i) {
    c.differ += a[i] != b[i];
    if (i % R >= 4 && i % R < 7) c.moved = std::max(c.moved, std::abs(a[i]));  // velocity
  }
  return c;
}

}  // namespace gen4d::test
