//! Points carried by the deforming voxel grid: each point is anchored at rest in a voxel (or at
//! a node) and follows the nodes by trilinear interpolation. Shared by the output surface and
//! the splats of a run.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

#include "elastogen/VoxelSystem.hpp"
#include "geometry/Shape.hpp"
#include "parallel/Comm.hpp"

namespace gen4d::elastogen {

//! Where a point sits at rest: global node `base` (the lower corner of its voxel, or the node
//! itself) and its local coordinates `t` in that voxel (0 for a node; outside [0, 1] when
//! extrapolated).
struct PointAnchor {
  long id = 0;
  std::array<long, 3> base{0, 0, 0};
  std::array<double, 3> t{0, 0, 0};
};

//! Solid state of any voxel of the grid: this rank's voxelization where it has one, else the
//! same centre test on demand (voxelize() decides each voxel from its global index alone, so
//! both agree on every rank).
class VoxelProbe {
 public:
  VoxelProbe(const VoxelSystem& sys, const geometry::Shape& shape);

  bool inside_grid(const std::array<long, 3>& c) const;
  bool solid(const std::array<long, 3>& c);
  //! Global x-fastest index of cell c.
  long linear(const std::array<long, 3>& c) const {
    return (c[2] * cells_[1] + c[1]) * cells_[0] + c[0];
  }
  const std::array<long, 3>& cells() const { return cells_; }

 private:
  const VoxelSystem& sys_;
  const geometry::Shape& shape_;
  std::array<long, 3> cells_;
  std::unordered_map<long, std::uint8_t> cache_;
};

//! Anchors world points in voxels from the rest state:
//! - a point is embedded in the voxel containing it (global cell floor((p - origin) / h),
//!   clamped to the grid) when that voxel is solid;
//! - otherwise (centre-sampled voxelization misses thin parts) in the nearest solid voxel
//!   (Euclidean distance from the point to the voxel's box; ties go to the lower global cell
//!   index) with its unclamped local coordinates, i.e. the trilinear map of that voxel is
//!   extrapolated. Extrapolation keeps the rest shape exact and stays exact for any affine
//!   motion of the voxel, where clamping would snap thin features onto the voxels.
//! Each rank anchors the points whose containing (clamped) voxel it owns, so every point is
//! anchored by exactly one rank whatever the decomposition.
class PointPlacer {
 public:
  PointPlacer(const VoxelSystem& sys, const geometry::Shape& shape);

  //! Anchors point `id` at world position p (3 values) when this rank owns its voxel.
  void add(long id, const double* p);
  //! The anchors made so far (this rank's), leaving none.
  std::vector<PointAnchor> take() { return std::move(anchors_); }
  //! Points this rank anchored in a voxel other than the one containing them, and the largest
  //! distance from such a point to its voxel, in voxel edge lengths.
  long extrapolated() const { return extrapolated_; }
  double max_extrapolation() const { return worst_; }

 private:
  const VoxelSystem& sys_;
  VoxelProbe probe_;
  std::vector<PointAnchor> anchors_;
  long extrapolated_ = 0;
  double worst_ = 0;
};

//! Anchored points distributed to the rank owning their base node. A point's position is
//! sum_m w_m x_m over the 8 corners m of its voxel with the weights of its rest local
//! coordinates, summed in a fixed corner order (zero weights skipped); its deformation
//! gradient is the gradient of that trilinear map at the same local point, d x / d X =
//! sum_m (x_m - x_0) (grad w_m)^T / h in the same fixed order. Each rank evaluates the points
//! it holds, so results do not depend on the decomposition. Construction and gathers are
//! collective.
class PointEmbedding {
 public:
  //! `anchors`: this rank's share of points 0 .. count - 1 (each anchored by exactly one rank;
  //! any rank may hold any anchor). `voxel_anchors`: every base is the lower corner of a voxel
  //! of the grid, which gradients need (node anchors may sit on the grid's far faces). `what`
  //! names the points in error messages. RuntimeError when the anchors do not cover every id.
  PointEmbedding(const VoxelSystem& sys, std::vector<PointAnchor> anchors, long count,
                 bool voxel_anchors, const std::string& what);

  long count() const { return count_; }
  //! Global ids of the points this rank evaluates, ascending.
  const std::vector<long>& local_ids() const { return ids_; }

  //! Positions of this rank's points (3 per point, order of local_ids()) from a node field on
  //! the ghosted box whose ghosts are current.
  void evaluate(const double* x, std::vector<double>& out) const;
  //! Deformation gradients of this rank's points (9 per point, row-major: F[3 d + a] =
  //! d x_d / d X_a). std::logic_error unless built with voxel anchors.
  void evaluate_gradients(const double* x, std::vector<double>& out) const;
  //! A per-point array of this rank's points (`width` values each, order of local_ids())
  //! assembled in id order on rank 0 (empty elsewhere). Collective.
  std::vector<double> gather(const std::vector<double>& local, int width) const;
  //! All positions in id order on rank 0 (empty elsewhere). Collective.
  std::vector<double> gather(const double* x) const;

 private:
  MPI_Comm comm_;
  int rank_ = 0, size_ = 1;
  long count_ = 0;
  Vec3d h_{1, 1, 1};  // cell edges
  bool voxel_anchors_ = false;
  std::vector<long> ids_;
  std::vector<std::size_t> base_;  //!< ghosted linear index of the base node
  std::vector<std::array<double, 3>> t_;
  std::vector<std::array<double, 8>> weights_;
  std::array<std::size_t, 8> corner_offset_{};
  std::vector<long> gather_ids_;  //!< rank 0: ids in gather order
};

}  // namespace gen4d::elastogen
