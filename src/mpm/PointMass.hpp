//! The deck's [[point_mass]] / [[attached_mass]] entries on MPM particles: an added density.
#pragma once

#include <vector>

#include "core/Config.hpp"
#include "mpm/Particles.hpp"
#include "parallel/Comm.hpp"

namespace gen4d::mpm {

//! Shares each entry's mass among the particles whose position (the reference position: call
//! it on freshly seeded particles) lies in its region [lo, hi], in proportion to their mass as
//! seeded: particle i gains m_i * mass / (the region's seeded particle mass), so the part moves
//! with them and gravity pulls on it; a particle in several regions gains each share. Region
//! masses are summed exactly over comm, so the masses do not depend on the rank count.
//! Collective. InputError naming the entry (`where`) when its region holds no particle.
void add_point_masses(MPI_Comm comm, const std::vector<PointMassConfig>& entries, Particles& p);

}  // namespace gen4d::mpm
