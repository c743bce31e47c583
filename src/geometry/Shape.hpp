//! Solid shapes as point-membership tests: primitives, unions, meshes, level sets.
#pragma once

#include <Eigen/Core>

#include <memory>
#include <vector>

#include "core/Config.hpp"

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

//! Union of one or more shapes.
class Union : public Shape {
 public:
  explicit Union(std::vector<std::unique_ptr<Shape>> parts);
  bool inside(const Eigen::Vector3d& p) const override;
  Aabb bounds() const override { return bounds_; }
  std::size_t size() const { return parts_.size(); }

 private:
  std::vector<std::unique_ptr<Shape>> parts_;
  Aabb bounds_;
};

//! Builds the union of the deck's geometry parts. Mesh and VDB parts are scaled, then
//! translated; their file paths are opened as given. Throws InputError on an empty list,
//! degenerate parameters, an unknown type, or a bad file.
std::unique_ptr<Shape> make_shape(const std::vector<GeometryConfig>& parts);

//! World-space bounds of the object (same as s.bounds()).
inline Aabb object_bounds(const Shape& s) { return s.bounds(); }

}  // namespace gen4d::geometry
