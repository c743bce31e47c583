// Generalized winding number (Jacobson et al. 2013) and its fast tree evaluation (Barill et
// al. 2018) with the order-1 (dipole) far field.
#include "geometry/Mesh.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>

namespace gen4d::geometry {
namespace {

constexpr int kLeafSize = 8;
constexpr int kMaxDepth = 100;  // median splits halve the range, so this is never reached
constexpr double kInvFourPi = 0.25 / 3.14159265358979323846;

}  // namespace

double triangle_winding(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                        const Eigen::Vector3d& c, const Eigen::Vector3d& q) {
  // Van Oosterom & Strackee: tan(Omega / 2) = det[a b c] / (|a||b||c| + (a.b)|c| + ...).
  const Eigen::Vector3d x = a - q, y = b - q, z = c - q;
  const double lx = x.norm(), ly = y.norm(), lz = z.norm();
  const double num = x.dot(y.cross(z));
  const double den = lx * ly * lz + x.dot(y) * lz + y.dot(z) * lx + z.dot(x) * ly;
  return 2.0 * std::atan2(num, den) * kInvFourPi;
}

double winding_number_exact(const Mesh& mesh, const Eigen::Vector3d& q) {
  double w = 0;
  for (const auto& t : mesh.triangles)
    w += triangle_winding(mesh.vertices[t[0]], mesh.vertices[t[1]], mesh.vertices[t[2]], q);
  return w;
}

WindingNumberTree::WindingNumberTree(const Mesh& mesh, double beta) : beta_(beta) {
  const int n = static_cast<int>(mesh.triangles.size());
  std::vector<int> order(n);
  std::vector<Eigen::Vector3d> centroids(n);
  for (int t = 0; t < n; ++t) {
    order[t] = t;
    const auto& tri = mesh.triangles[t];
    centroids[t] = (mesh.vertices[tri[0]] + mesh.vertices[tri[1]] + mesh.vertices[tri[2]]) / 3.0;
  }
  if (n == 0) return;
  nodes_.reserve(2 * (n / kLeafSize + 1));
  build(order, centroids, 0, n, 0);
  // Store corners in tree order so that a leaf reads one contiguous block.
  tris_.resize(n);
  for (int t = 0; t < n; ++t) {
    const auto& tri = mesh.triangles[order[t]];
    tris_[t] = {mesh.vertices[tri[0]], mesh.vertices[tri[1]], mesh.vertices[tri[2]]};
  }
  for (Node& node : nodes_) summarize(node);
}

int WindingNumberTree::build(std::vector<int>& order, std::vector<Eigen::Vector3d>& centroids,
                             int first, int count, int depth) {
  const int id = static_cast<int>(nodes_.size());
  nodes_.emplace_back();
  nodes_[id].first = first;
  nodes_[id].count = count;
  if (count <= kLeafSize || depth >= kMaxDepth) return id;
  Eigen::Vector3d lo = centroids[order[first]], hi = lo;
  for (int t = first; t < first + count; ++t) {
    lo = lo.cwiseMin(centroids[order[t]]);
    hi = hi.cwiseMax(centroids[order[t]]);
  }
  int axis = 0;
  (hi - lo).maxCoeff(&axis);
  const int half = count / 2;
  std::nth_element(order.begin() + first, order.begin() + first + half,
                   order.begin() + first + count,
                   [&](int l, int r) { return centroids[l][axis] < centroids[r][axis]; });
  const int left = build(order, centroids, first, half, depth + 1);
  const int right = build(order, centroids, first + half, count - half, depth + 1);
  nodes_[id].left = left;
  nodes_[id].right = right;
  return id;
}

void WindingNumberTree::summarize(Node& node) const {
  Eigen::Vector3d dipole = Eigen::Vector3d::Zero(), weighted = Eigen::Vector3d::Zero();
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  double area = 0;
  for (int t = node.first; t < node.first + node.count; ++t) {
    const auto& v = tris_[t];
    const Eigen::Vector3d n = 0.5 * (v[1] - v[0]).cross(v[2] - v[0]);
    const Eigen::Vector3d centroid = (v[0] + v[1] + v[2]) / 3.0;
    dipole += n;
    weighted += n.norm() * centroid;
    mean += centroid;
    area += n.norm();
  }
  // Degenerate (zero-area) clusters still need a finite expansion centre.
  node.center = area > 0 ? Eigen::Vector3d(weighted / area) : Eigen::Vector3d(mean / node.count);
  node.dipole = dipole;
  node.radius = 0;
  for (int t = node.first; t < node.first + node.count; ++t)
    for (const auto& v : tris_[t]) node.radius = std::max(node.radius, (v - node.center).norm());
}

double WindingNumberTree::operator()(const Eigen::Vector3d& q) const {
  if (nodes_.empty()) return 0;
  double w = 0;
  int stack[2 * kMaxDepth + 2];
  int top = 0;
  stack[top++] = 0;
  const double beta2 = beta_ * beta_;
  while (top > 0) {
    const Node& node = nodes_[stack[--top]];
    const Eigen::Vector3d d = node.center - q;
    const double dist2 = d.squaredNorm();
    if (dist2 > beta2 * node.radius * node.radius) {
      // Far field: the cluster acts as a point dipole, solid angle ~ N.(c - q) / |c - q|^3.
      w += node.dipole.dot(d) * kInvFourPi / (dist2 * std::sqrt(dist2));
    } else if (node.left < 0) {
      for (int t = node.first; t < node.first + node.count; ++t)
        w += triangle_winding(tris_[t][0], tris_[t][1], tris_[t][2], q);
    } else {
      stack[top++] = node.left;
      stack[top++] = node.right;
    }
  }
  return w;
}

}  // namespace gen4d::geometry
