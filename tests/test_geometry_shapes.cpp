// Procedural shapes, the deck factory and the voxelizer's indexing contract.
#include <gtest/gtest.h>

#include <cmath>

#include "core/Error.hpp"
#include "geometry/Shape.hpp"
#include "test_geometry_support.hpp"

namespace g = gen4d::geometry;
using Eigen::Vector3d;

using namespace geomtest;

namespace {

double ball_volume(double r) {
  return 4.0 / 3.0 * kPi * r * r * r;
}

gen4d::GeometryConfig sphere_config(gen4d::Vec3d c, double r) {
  gen4d::GeometryConfig g;
  g.type = "sphere";
  g.center = c;
  g.radius = r;
  return g;
}

// Splits an n-cell grid into 2x2x2 rank boxes, each grown by one ghost layer (so edge boxes
// reach index -1 and n), and counts cells where a box's voxelization differs from the full
// grid's (cells outside the grid must be empty).
long subbox_mismatches(const g::Shape& shape, const Vector3d& origin, double h,
                       const std::array<long, 3>& n) {
  std::vector<std::uint8_t> full, part;
  g::voxelize(shape, origin, h, {0, 0, 0}, n, full);
  EXPECT_GT(g::count_solid(full), 0);
  long mismatches = 0;
  for (int b = 0; b < 8; ++b) {
    std::array<long, 3> lo{}, hi{}, m{};
    for (int d = 0; d < 3; ++d) {
      const long half = n[d] / 2;
      lo[d] = ((b >> d) & 1 ? half : 0) - 1;
      hi[d] = ((b >> d) & 1 ? n[d] : half) + 1;
      m[d] = hi[d] - lo[d];
    }
    g::voxelize(shape, origin, h, lo, hi, part);
    EXPECT_EQ(part.size(), static_cast<std::size_t>(m[0] * m[1] * m[2]));
    for (long k = lo[2]; k < hi[2]; ++k)
      for (long j = lo[1]; j < hi[1]; ++j)
        for (long i = lo[0]; i < hi[0]; ++i) {
          const bool in_grid = i >= 0 && j >= 0 && k >= 0 && i < n[0] && j < n[1] && k < n[2];
          const std::uint8_t expected = in_grid ? full[(k * n[1] + j) * n[0] + i] : 0;
          mismatches += part[((k - lo[2]) * m[1] + (j - lo[1])) * m[0] + (i - lo[0])] != expected;
        }
  }
  return mismatches;
}

}  // namespace

TEST(GeometryShapes, BoxAlignedWithCellFacesIsExact) {
  const double h = 0.1;
  const Vector3d origin(-1.0, 2.0, 0.5);
  // Faces on cell boundaries: every centre is strictly inside or outside, so the count is exact.
  g::Box box(origin + h * Vector3d(3, 4, 5), origin + h * Vector3d(13, 24, 8));
  std::vector<std::uint8_t> occ;
  g::voxelize(box, origin, h, {0, 0, 0}, {20, 30, 10}, occ);
  ASSERT_EQ(occ.size(), 20u * 30u * 10u);
  EXPECT_EQ(g::count_solid(occ), 10 * 20 * 3);
  EXPECT_EQ(occ[(5 * 30 + 4) * 20 + 3], 1);    // first solid cell
  EXPECT_EQ(occ[(5 * 30 + 4) * 20 + 2], 0);    // its -x neighbour
  EXPECT_EQ(occ[(7 * 30 + 23) * 20 + 12], 1);  // last solid cell
  EXPECT_EQ(occ[(8 * 30 + 23) * 20 + 12], 0);  // its +z neighbour
}

TEST(GeometryShapes, UnalignedBoxWithinOneCellPerAxis) {
  const Vector3d lo(0.13, 0.27, -0.4), hi(1.13, 0.77, 0.35);
  g::Box box(lo, hi);
  const double h = 0.01;
  const Vector3d len = hi - lo;
  // Along each axis the number of centres in [lo, hi] is within one of len / h.
  const double bound = (h / len.x() + h / len.y() + h / len.z()) * len.prod();
  EXPECT_NEAR(voxel_volume(box, h), len.prod(), bound);
}

TEST(GeometryShapes, SphereVolume) {
  const double r = 0.37;
  g::Sphere sphere(Vector3d(0.011, -0.023, 0.0071), r);
  // At 16 cells per radius, centre sampling of a ball is typically within ~0.3% (lattice-point
  // counting error ~ r^(3/2) cells, relative (h/r)^(3/2)); 1% leaves margin for the offset.
  EXPECT_NEAR(voxel_volume(sphere, r / 16), ball_volume(r), 0.01 * ball_volume(r));
  EXPECT_TRUE(sphere.inside(Vector3d(0.011 + r * 0.999, -0.023, 0.0071)));
  EXPECT_FALSE(sphere.inside(Vector3d(0.011 + r * 1.001, -0.023, 0.0071)));
}

TEST(GeometryShapes, CapsuleVolume) {
  const Vector3d a(0.1, 0.2, 0.3), b(0.9, 0.6, -0.2);
  const double r = 0.15;
  g::Capsule capsule(a, b, r);
  const double exact = kPi * r * r * (b - a).norm() + ball_volume(r);
  EXPECT_NEAR(voxel_volume(capsule, r / 16), exact, 0.01 * exact);
  const g::Aabb box = capsule.bounds();
  EXPECT_NEAR(box.lo.x(), 0.1 - r, 1e-15);
  EXPECT_NEAR(box.hi.z(), 0.3 + r, 1e-15);
  // a == b degenerates to a ball.
  g::Capsule ball(a, a, r);
  EXPECT_NEAR(voxel_volume(ball, r / 16), ball_volume(r), 0.01 * ball_volume(r));
}

TEST(GeometryShapes, UnionOfOverlappingSpheresCountsLensOnce) {
  const double r = 0.3, d = 0.25;
  const auto shape = g::make_shape({sphere_config({0, 0, 0}, r), sphere_config({d, 0, 0}, r)});
  // Union = two balls minus the lens they share: pi (4r + d)(2r - d)^2 / 12.
  const double lens = kPi * (4 * r + d) * (2 * r - d) * (2 * r - d) / 12;
  const double exact = 2 * ball_volume(r) - lens;
  EXPECT_NEAR(voxel_volume(*shape, r / 16), exact, 0.01 * exact);
  EXPECT_NEAR(g::object_bounds(*shape).hi.x(), d + r, 1e-15);
}

TEST(GeometryShapes, FactoryBuildsEveryPrimitive) {
  gen4d::GeometryConfig box, capsule;
  box.type = "box";
  box.lo = {2, 0, 0};
  box.hi = {2.5, 0.4, 0.3};
  capsule.type = "capsule";
  capsule.a = {-2, 0, 0};
  capsule.b = {-2, 0, 0.5};
  capsule.radius = 0.1;
  const auto shape = g::make_shape({box, sphere_config({0, 0, 0}, 0.2), capsule});
  const double exact = 0.5 * 0.4 * 0.3 + ball_volume(0.2) + kPi * 0.01 * 0.5 + ball_volume(0.1);
  EXPECT_NEAR(voxel_volume(*shape, 0.01), exact, 0.02 * exact);
  EXPECT_TRUE(shape->inside(Vector3d(2.25, 0.2, 0.15)));
  EXPECT_TRUE(shape->inside(Vector3d(-2, 0, 0.25)));
  EXPECT_FALSE(shape->inside(Vector3d(1, 0, 0)));
}

TEST(GeometryShapes, FactoryRejectsDegenerateInput) {
  EXPECT_THROW(g::make_shape({}), gen4d::InputError);
  EXPECT_THROW(g::make_shape({sphere_config({0, 0, 0}, 0)}), gen4d::InputError);
  try {
    g::make_shape({sphere_config({0, 0, 0}, 1), sphere_config({0, 0, 0}, -1)});
    FAIL() << "negative radius accepted";
  } catch (const gen4d::InputError& e) {
    // The message points at the deck's second [[geometry]] table.
    EXPECT_NE(std::string(e.what()).find("[[geometry]] #2 (sphere)"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("radius"), std::string::npos) << e.what();
  }
  gen4d::GeometryConfig box;
  box.type = "box";
  box.lo = {0, 0, 0};
  box.hi = {1, 0, 1};  // zero thickness in y
  EXPECT_THROW(g::make_shape({box}), gen4d::InputError);
  gen4d::GeometryConfig capsule;
  capsule.type = "capsule";
  capsule.b = {1, 0, 0};
  EXPECT_THROW(g::make_shape({capsule}), gen4d::InputError);
  gen4d::GeometryConfig unknown;
  unknown.type = "torus";
  try {
    g::make_shape({unknown});
    FAIL() << "unknown type accepted";
  } catch (const gen4d::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("torus"), std::string::npos) << e.what();
  }
  gen4d::GeometryConfig mesh;
  mesh.type = "mesh";
  EXPECT_THROW(g::make_shape({mesh}), gen4d::InputError);  // no file
  mesh.file = "whatever.obj";
  mesh.scale = 0;
  EXPECT_THROW(g::make_shape({mesh}), gen4d::InputError);
}

TEST(GeometryShapes, SubBoxWithGhostsMatchesFullVoxelization) {
  const auto spheres =
      g::make_shape({sphere_config({0.5, 0.5, 0.5}, 0.3), sphere_config({0.8, 0.45, 0.6}, 0.17)});
  EXPECT_EQ(subbox_mismatches(*spheres, Vector3d(0, 0, 0), 1.0 / 40, {40, 40, 40}), 0);
  // An octahedron mesh whose vertices sit exactly on cell centres: the hardest ties.
  g::Mesh octahedron;
  octahedron.vertices = {{0.6, 0.5, 0.5},  {0.1, 0.5, 0.5},  {0.35, 0.8, 0.5},
                         {0.35, 0.2, 0.5}, {0.35, 0.5, 0.8}, {0.35, 0.5, 0.2}};
  octahedron.triangles = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4},
                          {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  const g::TriangleMesh mesh(octahedron, 1.0, Vector3d(0.1, 0, 0.05), "octahedron");
  EXPECT_GT(g::signed_volume(mesh.mesh()), 0);
  EXPECT_EQ(subbox_mismatches(mesh, Vector3d::Constant(-0.0125), 1.0 / 40, {38, 40, 36}), 0);
}

TEST(GeometryShapes, EmptyRangeAndCountSolid) {
  g::Sphere sphere(Vector3d::Zero(), 1);
  std::vector<std::uint8_t> occ{1, 1};
  g::voxelize(sphere, Vector3d::Zero(), 0.1, {3, 3, 3}, {3, 5, 5}, occ);
  EXPECT_TRUE(occ.empty());
  // A box far from the shape stays empty.
  g::voxelize(sphere, Vector3d::Zero(), 0.1, {100, 100, 100}, {104, 103, 102}, occ);
  EXPECT_EQ(occ.size(), 24u);
  EXPECT_EQ(g::count_solid(occ), 0);
  EXPECT_EQ(g::count_solid({0, 1, 2, 0, 255}), 3);
}
