//! Splat objects of a deck: a trained 3DGS object placed in the scene, splats that make any
//! solid renderable, and the solid a splat object occupies (for voxel solvers).
#pragma once

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <unordered_map>
#include <utility>

#include "core/Config.hpp"
#include "gaussians/Splats.hpp"
#include "geometry/Shape.hpp"

namespace gen4d::gaussians {

//! Reads the 3DGS PLY g.file, drops the Gaussians with opacity < g.opacity_threshold and maps
//! the rest by p -> g.scale * R p + g.translate, R the rotation by g.rotate_degrees about
//! g.rotate_axis. InputError naming the file for a bad file, a non-positive scale, a zero axis,
//! or when no Gaussian is left.
SplatSet load_geometry_splats(const GeometryConfig& g);

//! Maps splats by p -> scale * R p + t (R row-major, a rotation): positions, orientations
//! (q_R * q), standard deviations (times scale) and the view-dependent harmonics (rotated with
//! the object, so a splat seen along d shows the colour it showed along R^T d).
//! std::invalid_argument when scale is not positive or R is not a rotation.
void transform_splats(SplatSet& splats, double scale, const std::array<double, 9>& R,
                      const std::array<double, 3>& t);

//! Splats that render the solid `shape`: one isotropic Gaussian of standard deviation
//! spacing / 2 at each centre of a lattice of cells of edge `spacing` over the shape's bounding
//! box (anchored at its low corner) that lies inside the shape, in x-fastest order. SH degree 0
//! with the constant colour `color` (linear RGB in [0, 1]) and the given opacity. With the
//! lattice inset by spacing / 2, the splats' one-sigma extent meets the shape's boundary.
//! std::invalid_argument for a non-positive spacing or an opacity outside (0, 1); InputError when
//! the lattice would exceed 2^31 points.
SplatSet splats_from_shape(const geometry::Shape& shape, double spacing,
                           std::array<double, 3> color, double opacity = 0.95);

//! The solid a splat object occupies, resolved on cells of edge h anchored at `origin`: the
//! cell floor((p - origin) / h) is solid when it holds at least `min_count` splat centres
//! (occupied) or when the six axis-aligned rays from it all meet occupied cells (enclosed,
//! PhysGaussian's internal filling), so a shell of surface splats becomes a solid. Built on
//! sparse rows: memory follows the occupied cells, not the bounding box.
class SplatOccupancy : public geometry::Shape {
 public:
  //! std::invalid_argument for h <= 0 or min_count < 1; InputError when a splat lies more than
  //! 2^30 cells from the origin.
  SplatOccupancy(const SplatSet& splats, double h, std::array<double, 3> origin, int min_count = 1);
  bool inside(const Eigen::Vector3d& p) const override;
  //! The occupied cells' box (empty when none is).
  geometry::Aabb bounds() const override { return bounds_; }
  //! Number of occupied cells.
  std::size_t occupied_cells() const { return occupied_; }
  //! Number of solid cells (occupied or enclosed).
  long solid_cells() const;
  //! True when cell (i, j, k) is solid.
  bool solid(long i, long j, long k) const;

 private:
  using Range = std::pair<std::int32_t, std::int32_t>;  //!< lowest and highest occupied index
  double h_;
  Eigen::Vector3d origin_;
  //! Along axis a, the row through the other two coordinates (in increasing axis order).
  std::unordered_map<std::uint64_t, Range> rows_[3];
  std::size_t occupied_ = 0;
  geometry::Aabb bounds_;
};

}  // namespace gen4d::gaussians
