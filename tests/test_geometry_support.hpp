//! Helpers shared by the geometry test files: voxel volume of a shape, InputError checks, a
//! folder for the files the tests write.
#pragma once

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "core/Error.hpp"
#include "geometry/Shape.hpp"

namespace geomtest {

constexpr double kPi = 3.14159265358979323846;

//! `name` in the build tree's folder of geometry test assets (made when missing).
inline std::string asset_path(const std::string& name) {
  const std::filesystem::path dir =
      std::filesystem::path(GEN4D_BINARY_DIR) / "tests" / "geometry_assets";
  std::filesystem::create_directories(dir);
  return (dir / name).string();
}

//! Solid volume of the shape voxelized over its bounds (plus two cells) at spacing h.
inline double voxel_volume(const gen4d::geometry::Shape& s, double h) {
  const gen4d::geometry::Aabb b = s.bounds();
  // A generic offset: a ball centred exactly on a cell centre or corner is the lattice's
  // worst case (-1.2% at 12 cells per radius), which would say nothing about the shape.
  const Eigen::Vector3d origin = b.lo - h * Eigen::Vector3d(2.37, 2.21, 2.83);
  std::array<long, 3> hi{};
  for (int d = 0; d < 3; ++d) hi[d] = static_cast<long>(std::ceil((b.hi[d] - origin[d]) / h)) + 2;
  std::vector<std::uint8_t> occ;
  gen4d::geometry::voxelize(s, origin, h, {0, 0, 0}, hi, occ);
  return static_cast<double>(gen4d::geometry::count_solid(occ)) * h * h * h;
}

//! Runs f, expecting a one-line InputError whose message holds every needle.
template <class F>
void expect_input_error(F f, const std::vector<std::string>& needles) {
  try {
    f();
    ADD_FAILURE() << "no InputError; expected one mentioning " << needles.front();
  } catch (const gen4d::InputError& e) {
    const std::string msg = e.what();
    std::printf("  InputError: %s\n", msg.c_str());
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    for (const auto& n : needles) EXPECT_NE(msg.find(n), std::string::npos) << msg;
  }
}

}  // namespace geomtest
