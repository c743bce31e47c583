//! Triangle meshes and their OBJ / STL readers.
#pragma once

#include <Eigen/Core>

#include <array>
#include <string>
#include <vector>

namespace gen4d::geometry {

//! Indexed triangle soup; orientation follows the file (counter-clockwise seen from outside).
struct Mesh {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<std::array<int, 3>> triangles;
};

//! Wavefront OBJ: `v` and `f` records (polygons fan-triangulated; 1-based, negative and
//! v/vt/vn indices); other records are ignored. Throws InputError naming file and line.
Mesh read_obj(const std::string& path);

//! STL, ASCII or binary (binary is recognised by its size, since binary headers may also
//! begin with "solid"). Throws InputError naming the file and the triangle index.
Mesh read_stl(const std::string& path);

//! Dispatches on the extension (.obj or .stl, any case).
Mesh read_mesh(const std::string& path);

//! Sum of the signed volumes of the cones from `apex` to each triangle: the enclosed volume
//! of a closed, outward-oriented mesh (any apex). For a mesh with holes it counts each hole
//! as capped by the cones, so an apex on the plane of the holes gives the capped volume.
double signed_volume(const Mesh& mesh, const Eigen::Vector3d& apex = Eigen::Vector3d::Zero());

}  // namespace gen4d::geometry
