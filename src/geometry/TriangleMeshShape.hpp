//! Solid bounded by a (possibly open or holed) triangle mesh, via the winding number.
#pragma once

#include <memory>
#include <string>

#include "geometry/Mesh.hpp"
#include "geometry/Shape.hpp"
#include "geometry/WindingNumber.hpp"

namespace gen4d::geometry {

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

}  // namespace gen4d::geometry
