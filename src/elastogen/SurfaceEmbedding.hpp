//! A triangle surface carried by the deforming voxel grid: the deck's input mesh, or the
//! boundary of the solid voxels, whose vertices follow the nodes by trilinear interpolation.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/Config.hpp"
#include "elastogen/PointEmbedding.hpp"
#include "elastogen/VoxelSystem.hpp"
#include "geometry/Shape.hpp"

namespace gen4d::elastogen {

enum class SurfaceSource {
  Mesh,   //!< the vertices and triangles of the deck's mesh part(s), in the deck's frame
  Voxels  //!< the faces between solid voxels and empty space (2 triangles each)
};

//! Source for output.surface_source: "mesh" and "voxels" as named; "auto" is Mesh when every
//! [[geometry]] part is a mesh (several mesh parts are concatenated), else Voxels.
SurfaceSource choose_surface_source(const Config& cfg);

//! Vertex placement (fixed at construction, from the rest state; see PointEmbedding.hpp):
//! - Mesh vertex: anchored by PointPlacer, in the voxel containing it, or extrapolated from the
//!   nearest solid voxel when the voxelization missed it.
//! - Voxel-boundary vertex: a grid node, placed exactly at that node.
//! A vertex's position is then the trilinear interpolation of its voxel's corners, evaluated by
//! the rank owning that voxel (or node), so the result does not depend on the decomposition.
//! Construction and gather() are collective.
class SurfaceEmbedding {
 public:
  //! `shape` is the object the voxels were made from (consulted for the occupancy of voxels
  //! this rank did not voxelize). Throws InputError when the source is Mesh and a part of the
  //! shape is not a triangle mesh, RuntimeError for more than 2^31 - 1 vertices.
  SurfaceEmbedding(const VoxelSystem& sys, const geometry::Shape& shape, SurfaceSource source);

  SurfaceSource source() const { return source_; }
  long vertex_count() const { return vertex_count_; }
  long triangle_count() const { return triangle_count_; }
  //! Mesh vertices embedded in a voxel other than the one containing them (global), and the
  //! largest distance from such a vertex to its voxel, in voxel edge lengths.
  long extrapolated_vertices() const { return extrapolated_; }
  double max_extrapolation() const { return max_extrapolation_; }

  //! Triangles (vertex ids) on rank 0; empty on the other ranks.
  const std::vector<std::array<std::int32_t, 3>>& triangles() const { return triangles_; }
  //! Global ids of the vertices this rank evaluates, ascending.
  const std::vector<long>& local_ids() const { return points_->local_ids(); }

  //! Positions of this rank's vertices (3 per vertex, order of local_ids()) from a node field
  //! on the ghosted box whose ghosts are current.
  void evaluate(const double* x, std::vector<double>& out) const { points_->evaluate(x, out); }
  //! All vertex positions in id order on rank 0 (empty elsewhere). Collective.
  std::vector<double> gather(const double* x) const { return points_->gather(x); }

 private:
  //! This rank's anchors of the mesh vertices.
  std::vector<PointAnchor> build_mesh(const geometry::Shape& shape);
  //! Rank 0: the boundary quads' triangles and one anchor per boundary node.
  std::vector<PointAnchor> build_voxels(const geometry::Shape& shape);

  const VoxelSystem& sys_;
  MPI_Comm comm_;
  int rank_ = 0, size_ = 1;
  SurfaceSource source_;
  long vertex_count_ = 0, triangle_count_ = 0, extrapolated_ = 0;
  double max_extrapolation_ = 0;
  std::vector<std::array<std::int32_t, 3>> triangles_;
  std::unique_ptr<PointEmbedding> points_;
};

}  // namespace gen4d::elastogen
