// Mesh readers, winding numbers and mesh voxelization, on generated and real meshes.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>

#include "core/Error.hpp"
#include "geometry/Shape.hpp"
#include "test_geometry_support.hpp"

namespace g = gen4d::geometry;
namespace fs = std::filesystem;
using Eigen::Vector3d;

using namespace geomtest;

namespace {

std::string shared_mesh(const std::string& name) {
  return (std::filesystem::path(GEN4D_SHARED_DIR) / "data" / "meshes" / name).string();
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

// Unit icosphere: the icosahedron with every triangle split in four, vertices pushed to the
// sphere; faces are counter-clockwise seen from outside.
g::Mesh icosphere(int subdivisions) {
  const double t = (1 + std::sqrt(5.0)) / 2;
  g::Mesh m;
  m.vertices = {{-1, t, 0},  {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
                {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
  for (auto& v : m.vertices) v.normalize();
  m.triangles = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                 {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                 {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                 {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int s = 0; s < subdivisions; ++s) {
    std::map<std::pair<int, int>, int> midpoint;
    auto mid = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      auto it = midpoint.find(key);
      if (it != midpoint.end()) return it->second;
      m.vertices.push_back((m.vertices[a] + m.vertices[b]).normalized());
      return midpoint[key] = static_cast<int>(m.vertices.size()) - 1;
    };
    std::vector<std::array<int, 3>> finer;
    for (const auto& f : m.triangles) {
      const int ab = mid(f[0], f[1]), bc = mid(f[1], f[2]), ca = mid(f[2], f[0]);
      finer.insert(finer.end(), {{f[0], ab, ca}, {f[1], bc, ab}, {f[2], ca, bc}, {ab, bc, ca}});
    }
    m.triangles = std::move(finer);
  }
  return m;
}

void write_obj(const std::string& path, const g::Mesh& m) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  std::fprintf(f, "# icosphere, %zu faces\no sphere\n", m.triangles.size());
  for (const auto& v : m.vertices) std::fprintf(f, "v %.17g %.17g %.17g\n", v.x(), v.y(), v.z());
  for (const auto& t : m.triangles) std::fprintf(f, "f %d %d %d\n", t[0] + 1, t[1] + 1, t[2] + 1);
  std::fclose(f);
}

// The header deliberately starts with "solid", as many exporters' binary files do.
void write_binary_stl(const std::string& path, const g::Mesh& m) {
  std::string bytes(80, ' ');
  std::memcpy(bytes.data(), "solid icosphere (binary)", 24);
  const auto n = static_cast<std::uint32_t>(m.triangles.size());
  bytes.append(reinterpret_cast<const char*>(&n), 4);
  for (const auto& t : m.triangles) {
    float rec[12] = {0, 0, 0};
    for (int c = 0; c < 3; ++c)
      for (int d = 0; d < 3; ++d) rec[3 + 3 * c + d] = static_cast<float>(m.vertices[t[c]][d]);
    bytes.append(reinterpret_cast<const char*>(rec), sizeof(rec));
    bytes.append(2, '\0');
  }
  write_text(path, bytes);
}

void write_ascii_stl(const std::string& path, const g::Mesh& m) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  std::fprintf(f, "solid icosphere\n");
  for (const auto& t : m.triangles) {
    std::fprintf(f, "  facet normal 0 0 0\n    outer loop\n");
    for (int c = 0; c < 3; ++c) {
      const Vector3d& v = m.vertices[t[c]];
      std::fprintf(f, "      vertex %.9e %.9e %.9e\n", v.x(), v.y(), v.z());
    }
    std::fprintf(f, "    endloop\n  endfacet\n");
  }
  std::fprintf(f, "endsolid icosphere\n");
  std::fclose(f);
}

struct WindingError {
  double max = 0, mean = 0;
  int misclassified = 0;
};

// Fast vs exact winding numbers at random points in the mesh's box grown by 20%.
WindingError compare_winding(const g::Mesh& mesh, int samples) {
  g::Aabb box;
  for (const auto& v : mesh.vertices) box.extend(v);
  const Vector3d pad = 0.2 * (box.hi - box.lo);
  std::mt19937 rng(12345);
  std::uniform_real_distribution<double> u(0, 1);
  const g::WindingNumberTree tree(mesh);
  WindingError err;
  for (int s = 0; s < samples; ++s) {
    const Vector3d t(u(rng), u(rng), u(rng));
    const Vector3d p = (box.lo - pad) + t.cwiseProduct(box.hi - box.lo + 2 * pad);
    const double exact = g::winding_number_exact(mesh, p), fast = tree(p);
    err.max = std::max(err.max, std::abs(fast - exact));
    err.mean += std::abs(fast - exact) / samples;
    err.misclassified += (fast >= 0.5) != (exact >= 0.5);
  }
  return err;
}

// Boundary loops of an open mesh: chains of directed edges whose opposite edge is missing.
std::vector<std::vector<int>> boundary_loops(const g::Mesh& m) {
  std::map<std::pair<int, int>, int> edges;
  for (const auto& t : m.triangles)
    for (int c = 0; c < 3; ++c) ++edges[{t[c], t[(c + 1) % 3]}];
  std::map<int, int> next;
  for (const auto& [e, count] : edges)
    if (!edges.count({e.second, e.first})) next[e.first] = e.second;
  std::vector<std::vector<int>> loops;
  std::map<int, bool> seen;
  for (const auto& [start, unused] : next) {
    std::vector<int> loop;
    for (int v = start; !seen[v] && next.count(v); v = next[v]) {
      seen[v] = true;
      loop.push_back(v);
    }
    if (!loop.empty()) loops.push_back(loop);
  }
  return loops;
}

// Times the voxelization of a shape over its bounds; returns the solid volume.
double timed_voxel_volume(const g::Shape& s, double h, const std::string& name) {
  const auto t0 = std::chrono::steady_clock::now();
  const double v = voxel_volume(s, h);
  const double dt = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const g::Aabb b = s.bounds();
  const Vector3d cells = (b.hi - b.lo) / h;
  std::printf("%s: voxelized ~%.0f cells (h = %g) in %.2f s\n", name.c_str(), cells.prod(), h, dt);
  return v;
}

}  // namespace

TEST(GeometryMesh, IcosphereVolumeFromObjAndStl) {
  const g::Mesh sphere = icosphere(4);
  ASSERT_EQ(sphere.triangles.size(), 5120u);
  // The inscribed polyhedron is a little smaller than the ball (here by 0.22%); the rest of
  // the 2% budget covers centre sampling at 12 cells per radius (typically a few 0.1%) and
  // float32 rounding in binary STL (1e-7, negligible).
  const double poly = g::signed_volume(sphere);
  EXPECT_LT(poly, 4.0 / 3.0 * kPi);
  EXPECT_GT(poly, 0.997 * 4.0 / 3.0 * kPi);
  const std::string obj = asset_path("icosphere.obj"), bin = asset_path("icosphere_bin.stl"),
                    ascii = asset_path("icosphere_ascii.stl");
  write_obj(obj, sphere);
  write_binary_stl(bin, sphere);
  write_ascii_stl(ascii, sphere);
  const double scale = 0.25;
  const Vector3d shift(0.31, -0.17, 0.05);
  const double exact = 4.0 / 3.0 * kPi * scale * scale * scale;
  for (const std::string& path : {obj, bin, ascii}) {
    const auto shape = g::load_triangle_mesh(path, scale, shift);
    EXPECT_EQ(shape->mesh().triangles.size(), 5120u) << path;
    EXPECT_NEAR(shape->bounds().hi.x(), shift.x() + scale, 1e-6) << path;
    EXPECT_TRUE(shape->inside(shift));
    EXPECT_FALSE(shape->inside(shift + Vector3d(0, 0, 1.01 * scale)));
    const double v = voxel_volume(*shape, scale / 12);
    std::printf("%s: voxel volume / ball volume - 1 = %.2f%%\n", fs::path(path).filename().c_str(),
                100 * (v / exact - 1));
    EXPECT_NEAR(v, exact, 0.02 * exact) << path;
  }
}

TEST(GeometryMesh, ObjPolygonsIndicesAndComments) {
  // Unit cube: quads fan-triangulated, v/vt/vn and v//vn forms, negative indices, CRLF.
  const std::string path = asset_path("cube.obj");
  write_text(path,
             "# cube\r\nmtllib none.mtl\r\no cube\r\n"
             "v 0 0 0\r\nv 1 0 0\r\nv 1 1 0\r\nv 0 1 0\r\n"
             "v 0 0 1\r\nv 1 0 1 # trailing comment\r\nv 1 1 1\r\nv 0 1 1\r\n"
             "vt 0 0\nvn 0 0 1\ns off\n"
             "f 1 4 3 2\n"
             "f 5/1/1 6/1/1 7/1/1 8/1/1\n"
             "f -8//1 -7//1 -3//1 -4//1\n"
             "f 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n");
  const g::Mesh cube = g::read_obj(path);
  EXPECT_EQ(cube.vertices.size(), 8u);
  ASSERT_EQ(cube.triangles.size(), 12u);
  EXPECT_NEAR(g::signed_volume(cube), 1.0, 1e-14);
  EXPECT_NEAR(g::signed_volume(cube, Vector3d(0.3, 5, -2)), 1.0, 1e-12);
  gen4d::GeometryConfig part;
  part.type = "mesh";
  part.file = path;
  part.scale = 2;
  part.translate = {1, 1, 1};
  const auto shape = g::make_shape({part});
  // The edge is a whole number of cells, so exactly 20^3 centres fall inside.
  EXPECT_NEAR(voxel_volume(*shape, 0.1), 8.0, 1e-9);
  EXPECT_TRUE(shape->inside(Vector3d(2, 2, 2)));
  EXPECT_FALSE(shape->inside(Vector3d(3.5, 2, 2)));
}

TEST(GeometryMesh, MalformedFilesNameFileAndLocation) {
  const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  const std::string bad_number = asset_path("bad_number.obj");
  write_text(bad_number, "# header\nv 0 0 0\nv 1 0.x5 0\nv 0 1 0\nf 1 2 3\n");
  expect_input_error([&] { g::read_obj(bad_number); }, {"bad_number.obj:3", "0.x5"});
  const std::string nan_coord = asset_path("nan_coord.obj");
  write_text(nan_coord, "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n");
  expect_input_error([&] { g::read_obj(nan_coord); }, {"nan_coord.obj:2"});
  const std::string bad_index = asset_path("bad_index.obj");
  write_text(bad_index, tri + "f 1 2 3\nf 1 2 4\n");
  expect_input_error([&] { g::read_obj(bad_index); }, {"bad_index.obj:5", "out of range"});
  const std::string bad_relative = asset_path("bad_relative.obj");
  write_text(bad_relative, tri + "f -1 -2 -4\n");
  expect_input_error([&] { g::read_obj(bad_relative); }, {"bad_relative.obj:4", "-4"});
  const std::string zero_index = asset_path("zero_index.obj");
  write_text(zero_index, tri + "f 0 1 2\n");
  expect_input_error([&] { g::read_obj(zero_index); }, {"zero_index.obj:4"});
  const std::string no_faces = asset_path("no_faces.obj");
  write_text(no_faces, tri);
  expect_input_error([&] { g::read_obj(no_faces); }, {"no_faces.obj", "no faces"});
  fs::create_directories(asset_path("dir.obj"));
  const std::string empty_obj = asset_path("empty.obj"), empty_stl = asset_path("empty.stl");
  write_text(empty_obj, "");
  write_text(empty_stl, "");
  expect_input_error([&] { g::read_mesh(empty_obj); }, {"empty.obj"});
  expect_input_error([&] { g::read_mesh(empty_stl); }, {"empty.stl", "empty"});
  expect_input_error([&] { g::read_mesh(asset_path("missing.obj")); }, {"missing.obj"});
  expect_input_error([&] { g::read_mesh(asset_path("missing.stl")); }, {"missing.stl"});
  expect_input_error([&] { g::read_mesh(asset_path("mesh.ply")); }, {"mesh.ply", ".ply"});
  expect_input_error([&] { g::read_mesh(asset_path("dir.obj")); }, {"dir.obj", "directory"});
  gen4d::GeometryConfig part;
  part.type = "mesh";
  part.file = asset_path("missing_part.obj");
  expect_input_error([&] { g::make_shape({part}); }, {"missing_part.obj"});
}

TEST(GeometryMesh, MalformedStlNamesTriangle) {
  const g::Mesh sphere = icosphere(2);  // 320 triangles
  const std::string good = asset_path("stl_good.stl");
  write_binary_stl(good, sphere);
  std::ifstream in(good, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_EQ(bytes.size(), 84u + 50u * 320u);
  const std::string truncated = asset_path("truncated.stl");
  write_text(truncated, bytes.substr(0, 84 + 50 * 100 + 17));
  expect_input_error([&] { g::read_stl(truncated); }, {"truncated.stl", "triangle 100"});
  const std::string nan_bin = asset_path("nan_binary.stl");
  std::string with_nan = bytes;
  const float nan = std::nanf("");
  std::memcpy(with_nan.data() + 84 + 50 * 7 + 12 + 4 * 4, &nan, 4);
  write_text(nan_bin, with_nan);
  expect_input_error([&] { g::read_stl(nan_bin); }, {"nan_binary.stl", "triangle 7"});
  const std::string facet = "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n";
  const std::string bad_ascii = asset_path("bad_ascii.stl");
  write_text(bad_ascii, "solid t\n" + facet + "vertex 0 1 0\nendloop\nendfacet\n" + facet +
                            "vertex 0 1 zero\nendloop\nendfacet\nendsolid t\n");
  expect_input_error([&] { g::read_stl(bad_ascii); }, {"bad_ascii.stl:13", "triangle 1", "zero"});
  const std::string cut_ascii = asset_path("cut_ascii.stl");
  write_text(cut_ascii, "solid t\n" + facet);
  expect_input_error([&] { g::read_stl(cut_ascii); }, {"cut_ascii.stl", "triangle 0"});
  const std::string no_tris = asset_path("no_triangles.stl");
  write_text(no_tris, "solid t\nendsolid t\n");
  expect_input_error([&] { g::read_stl(no_tris); }, {"no_triangles.stl"});
}

TEST(GeometryMesh, ExactWindingNumberIsIntegerForClosedMesh) {
  const g::Mesh sphere = icosphere(3);
  for (const Vector3d& p : {Vector3d(0, 0, 0), Vector3d(0.5, -0.3, 0.2), Vector3d(0.1, 0.9, 0)})
    EXPECT_NEAR(g::winding_number_exact(sphere, p), 1.0, 1e-10);
  for (const Vector3d& p : {Vector3d(1.2, 0, 0), Vector3d(0.9, 0.9, 0.1), Vector3d(5, 5, 5)})
    EXPECT_NEAR(g::winding_number_exact(sphere, p), 0.0, 1e-10);
  // Reversing the orientation flips the sign.
  g::Mesh flipped = sphere;
  for (auto& t : flipped.triangles) std::swap(t[1], t[2]);
  EXPECT_NEAR(g::winding_number_exact(flipped, Vector3d(0.2, 0.1, 0)), -1.0, 1e-10);
}

TEST(GeometryMesh, FastWindingNumberMatchesExact) {
  // The order-1 far field at beta = 2 errs by ~ (cluster solid angle) * r / d per cluster:
  // measured max 0.03-0.07 and mean ~0.01 on these meshes. 0.1 keeps every point whose
  // exact w is 0 or 1 far from the 1/2 threshold, so the solid is the exact one's.
  std::vector<std::pair<std::string, g::Mesh>> meshes{{"icosphere", icosphere(4)}};
  for (const char* name : {"stanford-bunny.obj", "suzanne.obj", "spot.obj"})
    if (fs::exists(shared_mesh(name))) meshes.emplace_back(name, g::read_obj(shared_mesh(name)));
  for (const auto& [name, mesh] : meshes) {
    const int samples = 1000;
    const WindingError e = compare_winding(mesh, samples);
    std::printf("%s: |fast - exact| max %.3g mean %.3g, misclassified %d / %d\n", name.c_str(),
                e.max, e.mean, e.misclassified, samples);
    EXPECT_LT(e.max, 0.1) << name;
    EXPECT_LT(e.mean, 0.02) << name;
    EXPECT_EQ(e.misclassified, 0) << name;
  }
}

TEST(GeometryMesh, StanfordBunnyWithHolesIsSolid) {
  const std::string path = shared_mesh("stanford-bunny.obj");
  if (!fs::exists(path)) GTEST_SKIP() << "shared meshes not present: " << path;
  const g::Mesh mesh = g::read_obj(path);
  ASSERT_EQ(mesh.triangles.size(), 69451u);
  const auto loops = boundary_loops(mesh);
  ASSERT_GE(loops.size(), 1u);
  g::Aabb box;
  for (const auto& v : mesh.vertices) box.extend(v);
  const double height = box.hi.y() - box.lo.y();  // +y is up; the base is at the lowest y
  // The holes sit in the underside, near the base. Cones from an apex among their rims cap
  // them with (almost) flat lids, so the signed volume about that apex is the closed bunny's;
  // about the origin the missing lids would shift it by 2%.
  Vector3d apex = Vector3d::Zero();
  int rim_vertices = 0;
  for (const auto& loop : loops)
    for (int vertex : loop) {
      apex += mesh.vertices[vertex];
      ++rim_vertices;
    }
  apex /= rim_vertices;
  const double reference = g::signed_volume(mesh, apex);
  std::printf("bunny: %zu holes, volume about base %.6g, about origin %.6g\n", loops.size(),
              reference, g::signed_volume(mesh));
  const g::TriangleMesh shape(mesh, 1.0, Vector3d::Zero(), path);
  const double volume = timed_voxel_volume(shape, height / 100, "bunny");
  std::printf("bunny: voxel volume %.6g (%.2f%%)\n", volume, 100 * (volume / reference - 1));
  EXPECT_NEAR(volume, reference, 0.03 * reference);
  for (const auto& loop : loops) {
    Vector3d centre = Vector3d::Zero();
    for (int vertex : loop) centre += mesh.vertices[vertex];
    centre /= static_cast<double>(loop.size());
    EXPECT_LT(centre.y() - box.lo.y(), 0.2 * height) << "hole not in the underside";
    // Just above a hole the winding number is well below 1 (0.7-0.9), yet above 1/2.
    const Vector3d above = centre + Vector3d(0, 0.04 * height, 0);
    EXPECT_TRUE(shape.inside(above)) << "above hole at y=" << centre.y();
    EXPECT_LT(shape.winding_number(above), 0.97) << "hole not seen from just above it";
  }
}

TEST(GeometryMesh, SpotIsClosedAndScales) {
  const std::string path = shared_mesh("spot.obj");
  if (!fs::exists(path)) GTEST_SKIP() << "shared meshes not present: " << path;
  gen4d::GeometryConfig part;
  part.type = "mesh";
  part.file = path;
  part.scale = 0.5;
  part.translate = {2, -1, 0.5};
  const auto shape = g::make_shape({part});
  const double reference = 0.125 * g::signed_volume(g::read_obj(path));
  const g::Aabb b = shape->bounds();
  const double v = timed_voxel_volume(*shape, (b.hi - b.lo).maxCoeff() / 80, "spot");
  std::printf("spot: voxel volume %.6g vs mesh %.6g (%.2f%%)\n", v, reference,
              100 * (v / reference - 1));
  EXPECT_NEAR(v, reference, 0.02 * reference);
}

TEST(GeometryMesh, SuzanneOpenMultiPartMatchesExactWinding) {
  const std::string path = shared_mesh("suzanne.obj");
  if (!fs::exists(path)) GTEST_SKIP() << "shared meshes not present: " << path;
  const auto shape = g::load_triangle_mesh(path, 1.0, Vector3d::Zero());
  const g::Aabb b = shape->bounds();
  EXPECT_TRUE(shape->inside(0.5 * (b.lo + b.hi)));  // middle of the head
  // Open, multi-part meshes give fractional w near their openings, the hardest case for the
  // far-field approximation: the tree's occupancy must equal the exact sum's wherever the
  // exact w is not within 0.1 of the threshold.
  const double h = (b.hi - b.lo).maxCoeff() / 40;
  const Vector3d origin = b.lo - h * Vector3d::Ones();
  std::array<long, 3> n{};
  for (int d = 0; d < 3; ++d) n[d] = static_cast<long>(std::ceil((b.hi[d] - origin[d]) / h)) + 1;
  std::vector<std::uint8_t> occ;
  g::voxelize(*shape, origin, h, {0, 0, 0}, n, occ);
  long solid = 0, mismatched = 0, ambiguous = 0;
  for (long k = 0; k < n[2]; ++k)
    for (long j = 0; j < n[1]; ++j)
      for (long i = 0; i < n[0]; ++i) {
        const Vector3d p = origin + h * Vector3d(i + 0.5, j + 0.5, k + 0.5);
        const double w = g::winding_number_exact(shape->mesh(), p);
        const bool fast = occ[(k * n[1] + j) * n[0] + i] != 0;
        solid += fast;
        if (std::abs(w - 0.5) < 0.1)
          ++ambiguous;
        else
          mismatched += fast != (w >= 0.5);
      }
  std::printf("suzanne: %ld solid cells, %ld near w = 1/2, %ld mismatched\n", solid, ambiguous,
              mismatched);
  EXPECT_GT(solid, 1000);
  EXPECT_EQ(mismatched, 0);
}
