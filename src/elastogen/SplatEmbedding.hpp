//! 3D Gaussian splats riding the deforming voxel grid (PhysGaussian seed §3.4-3.5): each splat's
//! mean follows the trilinear map of its voxel and its covariance and harmonics follow that map's
//! gradient F.
#pragma once

#include <memory>
#include <vector>

#include "elastogen/PointEmbedding.hpp"
#include "elastogen/VoxelSystem.hpp"
#include "gaussians/Kinematics.hpp"
#include "gaussians/Splats.hpp"
#include "geometry/Shape.hpp"

namespace gen4d::elastogen {

//! Splat i of the rest set is the point with id i, anchored by PointPlacer at its rest mean (in
//! the voxel containing it, or extrapolated from the nearest solid voxel). The rank owning that
//! voxel evaluates it: position x = sum_m w_m x_m and F = d x / d X at the splat's local point,
//! both summed in a fixed corner order, so they do not depend on the decomposition. Each rank
//! keeps the rest data of its own splats only. Construction and gather() are collective.
class SplatEmbedding {
 public:
  //! `rest`: every splat of the run, the same on every rank; `shape`: the object the voxels were
  //! made from (for the occupancy of voxels this rank did not voxelize). RuntimeError for more
  //! splats than a long can count (never) or a grid without solid voxels.
  SplatEmbedding(const VoxelSystem& sys, const geometry::Shape& shape,
                 const gaussians::SplatSet& rest);

  long count() const { return points_->count(); }
  int sh_degree() const { return local_.sh_degree; }
  //! Splats embedded in a voxel other than the one containing their mean (global), and the
  //! largest distance from such a mean to its voxel, in voxel edge lengths.
  long extrapolated() const { return extrapolated_; }
  double max_extrapolation() const { return max_extrapolation_; }
  //! Global ids of this rank's splats, ascending, and their rest data in that order.
  const std::vector<long>& local_ids() const { return points_->local_ids(); }
  const gaussians::SplatSet& local_rest() const { return local_; }
  const PointEmbedding& points() const { return *points_; }

  //! This rank's splats deformed by the node field x (ghosted box, ghosts current), in the
  //! order of local_ids(), their covariance and harmonics per `options`.
  gaussians::SplatFrame frame(const double* x, const gaussians::KinematicsOptions& options) const;
  //! Means (3 per splat) and deformation gradients (9 per splat, row-major) of every splat in id
  //! order on rank 0 (empty elsewhere). Collective.
  void gather(const double* x, std::vector<double>& positions, std::vector<double>& F) const;

 private:
  std::unique_ptr<PointEmbedding> points_;
  gaussians::SplatSet local_;
  long extrapolated_ = 0;
  double max_extrapolation_ = 0;
};

}  // namespace gen4d::elastogen
