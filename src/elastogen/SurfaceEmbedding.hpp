//! A triangle surface carried by the deforming voxel grid: the deck's input mesh, or the
//! boundary of the solid voxels, whose vertices follow the nodes by trilinear interpolation.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "core/Config.hpp"
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

//! Vertex placement (fixed at construction, from the rest state):
//! - Mesh vertex: embedded in the voxel containing it (global cell floor((p - origin) / h),
//!   clamped to the grid) when that voxel is solid. Centre-sampled voxelization misses thin
//!   parts, so a vertex may sit in an empty voxel; it is then embedded in the nearest solid
//!   voxel (Euclidean distance from the vertex to the voxel's box; ties go to the lower global
//!   cell index) with its unclamped local coordinates, i.e. the trilinear map of that voxel
//!   is extrapolated. Extrapolation keeps the rest shape exact and stays exact for any affine
//!   motion of the voxel, where clamping would snap thin features onto the voxels.
//! - Voxel-boundary vertex: a grid node, placed exactly at that node.
//! A vertex's position is then sum_m w_m x_m over the 8 corners m of its voxel, with the
//! weights of its rest local coordinates, summed in a fixed corner order (zero weights
//! skipped). Each rank evaluates the vertices of the voxels (or nodes) it owns, so the result
//! does not depend on the decomposition. Construction and gather() are collective.
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
  const std::vector<long>& local_ids() const { return ids_; }

  //! Positions of this rank's vertices (3 per vertex, order of local_ids()) from a node field
  //! on the ghosted box whose ghosts are current.
  void evaluate(const double* x, std::vector<double>& out) const;
  //! All vertex positions in id order on rank 0 (empty elsewhere). Collective.
  std::vector<double> gather(const double* x) const;

 private:
  struct Anchor {
    long id;
    std::array<long, 3> base;  //!< global node of the lower corner of the voxel (or the node)
    std::array<double, 3> t;   //!< local coordinates in that voxel (0 for a node)
  };
  void build_mesh(const geometry::Shape& shape);
  void build_voxels(const geometry::Shape& shape);
  //! Keeps the anchors whose voxel this rank owns and sends the others to their owners.
  void distribute(std::vector<Anchor> anchors);
  void finish(std::vector<Anchor> anchors);
  int owner_of_node(const std::array<long, 3>& n) const;

  const VoxelSystem& sys_;
  MPI_Comm comm_;
  int rank_ = 0, size_ = 1;
  SurfaceSource source_;
  long vertex_count_ = 0, triangle_count_ = 0, extrapolated_ = 0;
  double max_extrapolation_ = 0;
  std::vector<std::array<std::int32_t, 3>> triangles_;
  std::vector<long> ids_;
  std::vector<std::size_t> base_;  //!< ghosted linear index of the base node
  std::vector<std::array<double, 8>> weights_;
  std::array<std::size_t, 8> corner_offset_{};
  std::vector<int> gather_counts_, gather_displs_;  //!< rank 0: 3 * vertices per rank
  std::vector<long> gather_ids_;                    //!< rank 0: ids in gather order
  std::array<std::vector<long>, 3> owner_ends_;     //!< end of each process's node range per axis
  std::array<long, 3> procs_{1, 1, 1};
};

}  // namespace gen4d::elastogen
