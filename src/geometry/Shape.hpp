//! Solids as point-membership tests (primitives, unions, meshes, level sets) and voxelization.
#pragma once

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/Config.hpp"
#include "geometry/Mesh.hpp"

namespace gen4d::geometry {

//! Axis-aligned bounding box; an empty box has lo > hi.
struct Aabb {
  Eigen::Vector3d lo{Eigen::Vector3d::Constant(1e300)};
  Eigen::Vector3d hi{Eigen::Vector3d::Constant(-1e300)};

  bool empty() const { return (lo.array() > hi.array()).any(); }
  bool contains(const Eigen::Vector3d& p) const {
    return (p.array() >= lo.array()).all() && (p.array() <= hi.array()).all();
  }
  void extend(const Eigen::Vector3d& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  void extend(const Aabb& b) {
    lo = lo.cwiseMin(b.lo);
    hi = hi.cwiseMax(b.hi);
  }
};

//! A solid region of space. inside() must be false outside bounds(), so callers may skip
//! everything outside the box.
class Shape {
 public:
  virtual ~Shape() = default;
  virtual bool inside(const Eigen::Vector3d& p) const = 0;
  virtual Aabb bounds() const = 0;
};

//! Closed box [lo, hi].
class Box : public Shape {
 public:
  Box(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi);
  bool inside(const Eigen::Vector3d& p) const override;
  Aabb bounds() const override { return box_; }

 private:
  Aabb box_;
};

//! Closed ball.
class Sphere : public Shape {
 public:
  Sphere(const Eigen::Vector3d& center, double radius);
  bool inside(const Eigen::Vector3d& p) const override;
  Aabb bounds() const override;

 private:
  Eigen::Vector3d center_;
  double radius_;
};

//! Points within `radius` of the segment a-b (a == b gives a ball).
class Capsule : public Shape {
 public:
  Capsule(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double radius);
  bool inside(const Eigen::Vector3d& p) const override;
  Aabb bounds() const override;

 private:
  Eigen::Vector3d a_, b_;
  double radius_;
};

//! Flat-ended solid cylinder: points within `radius` of the axis a-b whose projection on the
//! axis lies between a and b (a != b).
class Cylinder : public Shape {
 public:
  Cylinder(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double radius);
  bool inside(const Eigen::Vector3d& p) const override;
  Aabb bounds() const override;

 private:
  Eigen::Vector3d a_, axis_;  //!< axis_ = b - a
  double len2_, radius_;
};

//! Union of one or more shapes.
class Union : public Shape {
 public:
  explicit Union(std::vector<std::unique_ptr<Shape>> parts);
  bool inside(const Eigen::Vector3d& p) const override;
  Aabb bounds() const override { return bounds_; }
  std::size_t size() const { return parts_.size(); }
  const Shape& part(std::size_t i) const { return *parts_[i]; }

 private:
  std::vector<std::unique_ptr<Shape>> parts_;
  Aabb bounds_;
};

//! Inside iff the generalized winding number is >= 1/2, which closes small holes and keeps
//! separate parts of open meshes sensible. World point = scale * file point + translate.
class TriangleMesh : public Shape {
 public:
  //! `source` names the mesh in error messages. Throws InputError when the mesh has no
  //! triangles or scale is not positive.
  TriangleMesh(Mesh mesh, double scale, const Eigen::Vector3d& translate,
               const std::string& source);
  bool inside(const Eigen::Vector3d& p) const override;
  Aabb bounds() const override { return bounds_; }
  double winding_number(const Eigen::Vector3d& p) const;
  const Mesh& mesh() const { return mesh_; }  //!< transformed to world space

 private:
  Mesh mesh_;
  std::unique_ptr<WindingNumberTree> tree_;
  Aabb bounds_;
};

//! Reads an OBJ or STL file and wraps it as a TriangleMesh.
std::unique_ptr<TriangleMesh> load_triangle_mesh(const std::string& path, double scale,
                                                 const Eigen::Vector3d& translate);

//! Inside iff the trilinearly interpolated signed distance is < 0. World point =
//! scale * VDB world point + translate.
class VdbLevelSet : public Shape {
 public:
  //! Reads `grid` from `path` (empty = the first float level-set grid). Throws InputError
  //! for a missing or unreadable file, an unknown grid (listing the names present), or a
  //! grid that is not a float level set.
  VdbLevelSet(const std::string& path, const std::string& grid, double scale,
              const Eigen::Vector3d& translate);
  ~VdbLevelSet() override;
  bool inside(const Eigen::Vector3d& p) const override;
  Aabb bounds() const override { return bounds_; }
  double signed_distance(const Eigen::Vector3d& p) const;  //!< in world units
  const std::string& grid_name() const { return grid_name_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string grid_name_;
  double scale_;
  Eigen::Vector3d translate_;
  Aabb bounds_;
};

//! Builds the union of the deck's geometry parts. Mesh and VDB parts are scaled, then
//! translated; their file paths are opened as given. Throws InputError on an empty list,
//! degenerate parameters, an unknown type, or a bad file.
std::unique_ptr<Shape> make_shape(const std::vector<GeometryConfig>& parts);

//! World-space bounds of the object (same as s.bounds()).
inline Aabb object_bounds(const Shape& s) {
  return s.bounds();
}

//! Fills occ for the cells with global index (i,j,k) in [cell_lo, cell_hi) (half-open; may
//! extend past the grid). Cell (i,j,k) spans origin + h*[i,i+1] x [j,j+1] x [k,k+1] and is
//! solid (1) iff its centre is inside the shape. Layout: x fastest,
//! occ[(k-klo)*ny*nx + (j-jlo)*nx + (i-ilo)]. The result for a cell depends only on its
//! global index, so a sub-box equals the same slice of a larger voxelization.
void voxelize(const Shape& s, const Eigen::Vector3d& origin, double h,
              const std::array<long, 3>& cell_lo, const std::array<long, 3>& cell_hi,
              std::vector<std::uint8_t>& occ);
//! The same with cells of edges spacing = (hx, hy, hz): cell (i,j,k) spans
//! origin + [i hx, (i+1) hx] x [j hy, (j+1) hy] x [k hz, (k+1) hz]. Equal edges give the
//! scalar form's cells exactly.
void voxelize(const Shape& s, const Eigen::Vector3d& origin, const Eigen::Vector3d& spacing,
              const std::array<long, 3>& cell_lo, const std::array<long, 3>& cell_hi,
              std::vector<std::uint8_t>& occ);

//! Number of non-zero entries.
long count_solid(const std::vector<std::uint8_t>& occ);

}  // namespace gen4d::geometry
