//! Solid from an OpenVDB narrow-band level set (negative inside).
#pragma once

#include <memory>
#include <string>

#include "geometry/Shape.hpp"

namespace gen4d::geometry {

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

}  // namespace gen4d::geometry
