// Primitive shapes, unions, the mesh solid and the deck factory.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "core/Error.hpp"
#include "geometry/Shape.hpp"

namespace gen4d::geometry {
namespace {

Eigen::Vector3d to_eigen(const Vec3d& v) {
  return {v[0], v[1], v[2]};
}

void require_positive(double value, const char* what) {
  if (!(value > 0) || !std::isfinite(value))
    throw InputError(fmt::format("{} must be positive and finite, got {}", what, value));
}

}  // namespace

Box::Box(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  if (!lo.allFinite() || !hi.allFinite() || (lo.array() >= hi.array()).any())
    throw InputError(
        fmt::format("box needs lo < hi in every axis, got lo=({}, {}, {}) hi=({}, {}, {})", lo.x(),
                    lo.y(), lo.z(), hi.x(), hi.y(), hi.z()));
  box_.lo = lo;
  box_.hi = hi;
}

bool Box::inside(const Eigen::Vector3d& p) const {
  return box_.contains(p);
}

Sphere::Sphere(const Eigen::Vector3d& center, double radius) : center_(center), radius_(radius) {
  require_positive(radius, "sphere radius");
  if (!center.allFinite()) throw InputError("sphere center must be finite");
}

bool Sphere::inside(const Eigen::Vector3d& p) const {
  return (p - center_).squaredNorm() <= radius_ * radius_;
}

Aabb Sphere::bounds() const {
  return {center_.array() - radius_, center_.array() + radius_};
}

Capsule::Capsule(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double radius)
    : a_(a), b_(b), radius_(radius) {
  require_positive(radius, "capsule radius");
  if (!a.allFinite() || !b.allFinite()) throw InputError("capsule ends must be finite");
}

bool Capsule::inside(const Eigen::Vector3d& p) const {
  const Eigen::Vector3d ab = b_ - a_;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0 ? std::clamp((p - a_).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (p - (a_ + t * ab)).squaredNorm() <= radius_ * radius_;
}

Aabb Capsule::bounds() const {
  return {a_.cwiseMin(b_).array() - radius_, a_.cwiseMax(b_).array() + radius_};
}

Cylinder::Cylinder(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double radius)
    : a_(a), axis_(b - a), len2_((b - a).squaredNorm()), radius_(radius) {
  require_positive(radius, "cylinder radius");
  if (!a.allFinite() || !b.allFinite()) throw InputError("cylinder ends must be finite");
  if (!(len2_ > 0)) throw InputError("cylinder ends a and b must differ");
}

bool Cylinder::inside(const Eigen::Vector3d& p) const {
  const Eigen::Vector3d r = p - a_;
  const double s = r.dot(axis_);
  if (s < 0 || s > len2_) return false;
  return r.squaredNorm() - s * s / len2_ <= radius_ * radius_;
}

Aabb Cylinder::bounds() const {
  // Each end disc reaches radius * sqrt(1 - n_d^2) along axis d, n the unit axis.
  const Eigen::Vector3d n = axis_ / std::sqrt(len2_);
  const Eigen::Vector3d reach =
      radius_ * (Eigen::Vector3d::Ones() - n.cwiseProduct(n)).cwiseMax(0.0).cwiseSqrt();
  const Eigen::Vector3d b = a_ + axis_;
  return {a_.cwiseMin(b) - reach, a_.cwiseMax(b) + reach};
}

Union::Union(std::vector<std::unique_ptr<Shape>> parts) : parts_(std::move(parts)) {
  if (parts_.empty()) throw InputError("the object has no geometry parts");
  for (const auto& part : parts_) bounds_.extend(part->bounds());
}

bool Union::inside(const Eigen::Vector3d& p) const {
  if (!bounds_.contains(p)) return false;
  for (const auto& part : parts_)
    if (part->inside(p)) return true;
  return false;
}

TriangleMesh::TriangleMesh(Mesh mesh, double scale, const Eigen::Vector3d& translate,
                           const std::string& source)
    : mesh_(std::move(mesh)) {
  if (mesh_.triangles.empty()) throw InputError(fmt::format("{}: mesh has no triangles", source));
  if (!(scale > 0) || !std::isfinite(scale))
    throw InputError(fmt::format("{}: mesh scale must be positive, got {}", source, scale));
  for (auto& v : mesh_.vertices) {
    v = scale * v + translate;
    bounds_.extend(v);
  }
  tree_ = std::make_unique<WindingNumberTree>(mesh_);
}

double TriangleMesh::winding_number(const Eigen::Vector3d& p) const {
  return (*tree_)(p);
}

bool TriangleMesh::inside(const Eigen::Vector3d& p) const {
  // Outside the bounding box the whole surface lies in a half-space, which subtends at most
  // 2 pi: w < 1/2 there, so the box test loses nothing.
  return bounds_.contains(p) && (*tree_)(p) >= 0.5;
}

std::unique_ptr<TriangleMesh> load_triangle_mesh(const std::string& path, double scale,
                                                 const Eigen::Vector3d& translate) {
  return std::make_unique<TriangleMesh>(read_mesh(path), scale, translate, path);
}

namespace {

std::unique_ptr<Shape> make_part(const GeometryConfig& g) {
  if (g.type == "box") return std::make_unique<Box>(to_eigen(g.lo), to_eigen(g.hi));
  if (g.type == "sphere") return std::make_unique<Sphere>(to_eigen(g.center), g.radius);
  if (g.type == "capsule") return std::make_unique<Capsule>(to_eigen(g.a), to_eigen(g.b), g.radius);
  if (g.type == "cylinder")
    return std::make_unique<Cylinder>(to_eigen(g.a), to_eigen(g.b), g.radius);
  if (g.type == "mesh" || g.type == "vdb") {
    if (g.file.empty()) throw InputError(fmt::format("{} part needs a file", g.type));
    require_positive(g.scale, "scale");
    if (g.type == "mesh") return load_triangle_mesh(g.file, g.scale, to_eigen(g.translate));
    return std::make_unique<VdbLevelSet>(g.file, g.grid, g.scale, to_eigen(g.translate));
  }
  if (g.type == "splats")
    throw InputError(
        "a splats part is not a solid shape: only the elastogen and mpm solvers take splat "
        "geometry");
  throw InputError(fmt::format(
      "unknown geometry type '{}' (expected box, sphere, capsule, cylinder, mesh or vdb)", g.type));
}

}  // namespace

std::unique_ptr<Shape> make_shape(const std::vector<GeometryConfig>& parts) {
  if (parts.empty()) throw InputError("the object has no geometry parts");
  std::vector<std::unique_ptr<Shape>> shapes;
  shapes.reserve(parts.size());
  for (std::size_t i = 0; i < parts.size(); ++i) {
    try {
      shapes.push_back(make_part(parts[i]));
    } catch (const InputError& e) {
      // Say which [[geometry]] table of the deck is at fault.
      throw InputError(fmt::format("[[geometry]] #{} ({}): {}", i + 1, parts[i].type, e.what()));
    }
  }
  if (shapes.size() == 1) return std::move(shapes.front());
  return std::make_unique<Union>(std::move(shapes));
}

}  // namespace gen4d::geometry
