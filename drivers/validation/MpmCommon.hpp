//! Shared by the MPM validation drivers: a solver built from a material and a particle shape,
//! and global reductions over particles.
#pragma once

#include <mpi.h>

#include <algorithm>
#include <functional>
#include <memory>
#include <vector>

#include "geometry/Shape.hpp"
#include "mpm/Seeding.hpp"
#include "mpm/Solver.hpp"

namespace gen4d::driver {

inline std::shared_ptr<const mpm::Material> mpm_material(const std::string& model,
                                                         std::map<std::string, double> values) {
  mpm::MaterialParams p;
  p.model = model;
  p.values = std::move(values);
  p.source = "driver";
  return mpm::make_material(p);
}

//! A cylinder on the z axis from z0 to z1, or its quarter x >= 0, y >= 0 (with symmetry planes).
struct AxisCylinder : geometry::Shape {
  AxisCylinder(double radius, double z_lo, double z_hi, bool quarter_only)
      : R(radius), z0(z_lo), z1(z_hi), quarter(quarter_only) {}
  double R, z0, z1;
  bool quarter;
  bool inside(const Eigen::Vector3d& p) const override {
    return (!quarter || (p.x() >= 0 && p.y() >= 0)) && p.x() * p.x() + p.y() * p.y() <= R * R &&
           p.z() >= z0 && p.z() <= z1;
  }
  geometry::Aabb bounds() const override {
    geometry::Aabb b;
    b.lo = Eigen::Vector3d(quarter ? 0 : -R, quarter ? 0 : -R, z0);
    b.hi = Eigen::Vector3d(R, R, z1);
    return b;
  }
};

//! Seeds `shape` on `grid` and distributes; returns the solver. Collective.
inline std::unique_ptr<mpm::Solver> mpm_solver(MPI_Comm comm, const mpm::GridSpec& grid,
                                               std::shared_ptr<const mpm::Material> material,
                                               const mpm::SolverOptions& opt,
                                               std::vector<BoundaryConfig> bcs,
                                               const geometry::Shape& shape, int ppa,
                                               const Vec3d& velocity = {0, 0, 0}) {
  auto solver = std::make_unique<mpm::Solver>(comm, grid, material, opt, std::move(bcs));
  solver->distribute(mpm::seed_particles(comm, grid, shape, ppa, *material, velocity));
  return solver;
}

//! Max over all particles of f(i) (collective).
inline double particle_max(MPI_Comm comm, const mpm::Particles& p,
                           const std::function<double(std::size_t)>& f) {
  double m = -1e300;
  for (std::size_t i = 0; i < p.size(); ++i) m = std::max(m, f(i));
  MPI_Allreduce(MPI_IN_PLACE, &m, 1, MPI_DOUBLE, MPI_MAX, comm);
  return m;
}

//! Advances to time `t_end` with stable substeps; returns the substeps taken.
inline long advance(mpm::Solver& s, double& t, double t_end) {
  long n = 0;
  while (t < t_end * (1 - 1e-12)) {
    const double dt = s.stable_dt(t_end - t);
    s.substep(t, dt);
    t = dt >= (t_end - t) * (1 - 1e-12) ? t_end : t + dt;
    ++n;
  }
  return n;
}

}  // namespace gen4d::driver
