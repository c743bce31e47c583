//! Particles from the deck's geometry: a regular lattice of particles_per_axis^3 points per
//! grid cell, kept where the solid is. Ids are dense in global cell order (z, y, x slowest to
//! fastest, then the lattice point), the same at any rank count.
#pragma once

#include <mpi.h>

#include "geometry/Shape.hpp"
#include "mpm/Material.hpp"
#include "mpm/Particles.hpp"
#include "mpm/Solver.hpp"

namespace gen4d::mpm {

//! Seeds the cells of `grid` inside `shape` (each rank a slab of z-layers), with initial
//! velocity `velocity`, mass density * volume and the material's initial state. Collective.
Particles seed_particles(MPI_Comm comm, const GridSpec& grid, const geometry::Shape& shape,
                         int particles_per_axis, const Material& material, const Vec3d& velocity);

}  // namespace gen4d::mpm
