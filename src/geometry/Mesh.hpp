//! Triangle meshes: OBJ / STL readers, enclosed volume and generalized winding numbers.
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

//! STL, ASCII or binary. Binary headers may also begin with "solid", so a file is binary when
//! its size matches the declared triangle count or its start holds non-text bytes. Throws
//! InputError naming the file and the triangle index (and line, for ASCII).
Mesh read_stl(const std::string& path);

//! Dispatches on the extension (.obj or .stl, any case).
Mesh read_mesh(const std::string& path);

//! Sum of the signed volumes of the cones from `apex` to each triangle: the enclosed volume
//! of a closed, outward-oriented mesh (any apex). For a mesh with holes it counts each hole
//! as capped by the cones, so an apex on the plane of the holes gives the capped volume.
double signed_volume(const Mesh& mesh, const Eigen::Vector3d& apex = Eigen::Vector3d::Zero());

//! Signed solid angle of triangle (a, b, c) seen from q, divided by 4 pi.
double triangle_winding(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                        const Eigen::Vector3d& c, const Eigen::Vector3d& q);

//! Exact O(N) winding number: the sum of triangle_winding over all triangles.
double winding_number_exact(const Mesh& mesh, const Eigen::Vector3d& q);

//! Fast winding number (Barill et al. 2018): a bounding-volume hierarchy over the triangles;
//! a cluster whose bounding ball (radius r) is farther than beta * r from the query is
//! replaced by its dipole (area-weighted normal at the area-weighted centroid), nearer
//! clusters are summed exactly. The dipole errs by ~ (cluster solid angle) * r / d; at
//! beta = 2 the total stays below ~0.07 on real meshes, so points whose exact w is 0 or 1
//! are never misclassified. Query cost is O(log N) for points away from the surface.
class WindingNumberTree {
 public:
  explicit WindingNumberTree(const Mesh& mesh, double beta = 2.0);
  double operator()(const Eigen::Vector3d& q) const;
  std::size_t node_count() const { return nodes_.size(); }

 private:
  struct Node {
    Eigen::Vector3d center;     //!< area-weighted centroid of the cluster
    Eigen::Vector3d dipole;     //!< sum of area * unit normal
    double radius = 0;          //!< all cluster vertices lie within this of center
    int first = 0, count = 0;   //!< triangle range (in tris_ order)
    int left = -1, right = -1;  //!< children; -1 for leaves
  };
  int build(std::vector<int>& order, std::vector<Eigen::Vector3d>& centroids, int first, int count,
            int depth);
  void summarize(Node& node) const;

  std::vector<std::array<Eigen::Vector3d, 3>> tris_;
  std::vector<Node> nodes_;
  double beta_;
};

}  // namespace gen4d::geometry
