//! Particles from the deck's geometry: a regular lattice of particles_per_axis^3 points per
//! grid cell, kept where the solid is. Ids are dense in global cell order (z, y, x slowest to
//! fastest, then the lattice point), the same at any rank count.
#pragma once

#include <cstdint>

#include "gaussians/Splats.hpp"
#include "geometry/Shape.hpp"
#include "mpm/Material.hpp"
#include "mpm/Particles.hpp"
#include "mpm/Solver.hpp"
#include "parallel/Comm.hpp"

namespace gen4d::mpm {

//! Seeds the cells of `grid` inside `shape` (each rank a slab of z-layers), with initial
//! velocity `velocity`, mass density * volume and the material's initial state. Collective.
Particles seed_particles(MPI_Comm comm, const GridSpec& grid, const geometry::Shape& shape,
                         int particles_per_axis, const Material& material, const Vec3d& velocity);

//! One particle per splat of `splats` at its mean (PhysGaussian): volume the volume of its grid
//! cell (floor((x - lo) / dx)) divided by the number of splats in that cell, mass density times
//! volume, id first_id + the splat's index, and the splat attributes of mpm/SplatParticles.hpp
//! (SH degree max(splats.sh_degree, sh_degree)) in Particles::extra. Every rank passes the same
//! set and seeds an equal share of it, so ids and values do not depend on the rank count.
//! InputError naming `where` for a splat outside the grid. Collective only in that error.
Particles seed_splats(MPI_Comm comm, const GridSpec& grid, const gaussians::SplatSet& splats,
                      const Material& material, const Vec3d& velocity, std::int64_t first_id,
                      int sh_degree = 0, const std::string& where = "splats");

}  // namespace gen4d::mpm
