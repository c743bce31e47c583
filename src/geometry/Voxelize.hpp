//! Cell occupancy of a shape on a uniform grid.
#pragma once

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <vector>

#include "geometry/Shape.hpp"

namespace gen4d::geometry {

//! Fills occ for the cells with global index (i,j,k) in [cell_lo, cell_hi) (half-open; may
//! extend past the grid). Cell (i,j,k) spans origin + h*[i,i+1] x [j,j+1] x [k,k+1] and is
//! solid (1) iff its centre is inside the shape. Layout: x fastest,
//! occ[(k-klo)*ny*nx + (j-jlo)*nx + (i-ilo)]. The result for a cell depends only on its
//! global index, so a sub-box equals the same slice of a larger voxelization.
void voxelize(const Shape& s, const Eigen::Vector3d& origin, double h,
              const std::array<long, 3>& cell_lo, const std::array<long, 3>& cell_hi,
              std::vector<std::uint8_t>& occ);

//! Number of non-zero entries.
long count_solid(const std::vector<std::uint8_t>& occ);

}  // namespace gen4d::geometry
