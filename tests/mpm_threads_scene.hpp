//! A scene for the MPM kernel tests: about 11k particles (above the serial threshold of the
//! host loops) of one model falling on a Coulomb floor and a wall, on a 0.025 m grid.
#pragma once

#include <map>
#include <memory>
#include <string>

#include "geometry/Shape.hpp"
#include "mpm/Seeding.hpp"
#include "mpm/Solver.hpp"
#include "mpm_test_util.hpp"

namespace gen4d::test {

inline std::unique_ptr<mpm::Solver> kernel_scene(MPI_Comm comm, const std::string& model,
                                                 bool allow_device = true) {
  mpm::MaterialParams p;
  p.model = model;
  p.values = {{"youngs_modulus", 2e5}, {"poisson_ratio", 0.3}, {"density", 1000}};
  if (model == "drucker_prager") p.values["friction_angle"] = 30;
  p.source = "test";
  const std::shared_ptr<const mpm::Material> m = mpm::make_material(p);
  mpm::GridSpec g;
  g.dx = 0.025;
  g.lo = {-0.3, -0.3, -0.3};
  g.cells = {40, 32, 36};
  mpm::SolverOptions opt;
  opt.max_dt = 1e-3;
  opt.allow_device = allow_device;
  const std::vector<BoundaryConfig> bcs = {
      mpm::surface_collider("separate", {0, 0, 0}, {0, 0, 1}, 0.4),
      mpm::surface_collider("slip", {0.3, 0, 0}, {-1, 0, 0})};
  auto solver = std::make_unique<mpm::Solver>(comm, g, m, opt, bcs);
  const geometry::Box box(Eigen::Vector3d(0, 0, 0.02), Eigen::Vector3d(0.3, 0.2, 0.35));
  solver->distribute(mpm::seed_particles(comm, g, box, 2, *m, {0.8, 0.1, -1.0}));
  return solver;
}

}  // namespace gen4d::test
