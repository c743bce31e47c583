// Surface files: PLY / OBJ round trips, located errors for malformed files, the sequence
// listing and pruning used by restarts, and PNG previews of a surface sequence.
#include <gtest/gtest.h>
#include <png.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>

#include "core/Error.hpp"
#include "io/PngPreview.hpp"
#include "io/SurfaceIO.hpp"
#include "png_test_util.hpp"
#include "test_io_support.hpp"

namespace gen4d::io {
namespace {

using namespace iotest;
namespace fs = std::filesystem;

//! A unit cube (8 vertices, 12 outward triangles) moved by `shift` along x; `awkward` puts
//! doubles in the coordinates that a round trip must keep to the last bit.
SurfaceMesh cube(double shift = 0.0, bool awkward = true) {
  SurfaceMesh m;
  for (int v = 0; v < 8; ++v) {
    if (awkward) {
      m.xyz.push_back(shift + ((v & 1) ? 1.0 / 3.0 : -0.0));
      m.xyz.push_back((v & 2) ? 0.1 + 0.2 : 1e-300);
      m.xyz.push_back((v & 4) ? 12345.678901234567 : -std::numeric_limits<double>::min());
    } else {
      m.xyz.insert(m.xyz.end(), {shift + (v & 1), double((v >> 1) & 1), double((v >> 2) & 1)});
    }
  }
  m.triangles = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                 {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  m.comments = {"gen4d test cube", "second line"};
  return m;
}

void expect_same_bits(const SurfaceMesh& a, const SurfaceMesh& b) {
  ASSERT_EQ(a.xyz.size(), b.xyz.size());
  for (std::size_t i = 0; i < a.xyz.size(); ++i) {
    EXPECT_EQ(std::signbit(a.xyz[i]), std::signbit(b.xyz[i])) << i;
    EXPECT_EQ(a.xyz[i], b.xyz[i]) << i;
  }
  EXPECT_EQ(a.triangles, b.triangles);
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

//! The message of the InputError that reading `path` throws ("" when none is thrown).
std::string read_error(const std::string& path) {
  try {
    read_surface(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(SurfaceFiles, PlyAndObjRoundTripEveryBit) {
  const std::string dir = scratch_dir("surface_roundtrip");
  const SurfaceMesh m = cube();
  for (SurfaceFormat f : {SurfaceFormat::Ply, SurfaceFormat::Obj}) {
    const std::string path = dir + "/" + surface_file_name(7, f);
    write_surface(path, m, f);
    const SurfaceMesh back = read_surface(path);
    expect_same_bits(m, back);
    EXPECT_EQ(back.comments, m.comments);
    EXPECT_EQ(file_bytes(path), surface_bytes(m, f));
  }
  EXPECT_EQ(surface_file_name(123, SurfaceFormat::Ply), "surface_000123.ply");
  // Binary PLY: header plus 24 bytes per vertex and 13 per triangle.
  const std::string ply = surface_bytes(m, SurfaceFormat::Ply);
  const std::size_t header = ply.find("end_header\n") + 11;
  EXPECT_EQ(ply.size() - header, 8u * 24u + 12u * 13u);
  EXPECT_EQ(ply.rfind("ply\nformat binary_little_endian 1.0\ncomment gen4d test cube\n", 0), 0u);
  // Nothing but the two files: the temporaries were renamed.
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator{}), 2);
}

TEST(SurfaceFiles, ReadsAsciiPlyWithOtherPropertiesAndPolygons) {
  const std::string dir = scratch_dir("surface_ascii");
  write_text(dir + "/a.ply",
             "ply\r\nformat ascii 1.0\r\ncomment hello\r\nelement vertex 4\r\n"
             "property float x\r\nproperty float y\r\nproperty float z\r\nproperty uchar red\r\n"
             "element face 1\r\nproperty list uchar uint vertex_index\r\nproperty int flags\r\n"
             "element edge 1\r\nproperty int vertex1\r\nproperty int vertex2\r\nend_header\r\n"
             "0 0 0 255\r\n1 0 0 0\r\n1 1 0 0\r\n0 1 0 7\r\n4 0 1 2 3 9\r\n0 1\r\n");
  const SurfaceMesh m = read_surface(dir + "/a.ply");
  ASSERT_EQ(m.vertex_count(), 4u);
  EXPECT_EQ(m.xyz[6], 1.0);
  ASSERT_EQ(m.triangles.size(), 2u);  // the quad, fan-triangulated
  EXPECT_EQ(m.triangles[1], (std::array<std::int32_t, 3>{0, 2, 3}));
  EXPECT_EQ(m.comments, std::vector<std::string>{"hello"});
}

TEST(SurfaceFiles, MalformedFilesNameFileAndPlace) {
  const std::string dir = scratch_dir("surface_bad");
  const std::string head =
      "ply\nformat ascii 1.0\nelement vertex 2\nproperty double x\nproperty double y\n"
      "property double z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
  struct Case {
    std::string name, text, expect;
  };
  const std::string good_ply = surface_bytes(cube(), SurfaceFormat::Ply);
  const std::vector<Case> cases = {
      {"notply.ply", "solid x\n", "notply.ply:1: PLY header: not a PLY file"},
      {"endian.ply", "ply\nformat binary_big_endian 1.0\nend_header\n",
       "endian.ply:2: PLY header: format 'binary_big_endian' is not supported"},
      {"noend.ply", "ply\nformat ascii 1.0\nelement vertex 1\n",
       "noend.ply:3: PLY header: file ends before 'end_header'"},
      {"noz.ply",
       "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
       "property float y\nend_header\n0 0\n",
       "noz.ply: PLY header: element vertex has no scalar property 'z'"},
      {"word.ply", head + "0 0 0\n1 zero 0\n3 0 1 1\n",
       "word.ply:11: vertex 1: not a number: 'zero'"},
      {"extra.ply", head + "0 0 0 5\n", "extra.ply:10: vertex 0: 1 value(s) more"},
      {"short.ply", head + "0 0 0\n",
       "short.ply:10: vertex 1: file ends early (2 vertex element(s) declared)"},
      {"range.ply", head + "0 0 0\n1 1 1\n3 0 1 9\n",
       "range.ply: face 0: vertex index 9 out of range (2 vertices)"},
      {"nan.ply", head + "0 nan 0\n1 1 1\n3 0 1 1\n",
       "nan.ply:10: vertex 0: coordinate is not finite"},
      {"truncated.ply", good_ply.substr(0, good_ply.size() - 20),
       "truncated.ply: face 10: file is truncated"},
      {"badface.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n",
       "badface.obj:4: face index 4 out of range (3 vertices so far)"},
      {"badv.obj", "v 0 0\n", "badv.obj:1: a vertex needs 3 coordinates"},
      {"surface.stl", "solid\n", "surface.stl: not a surface file"},
  };
  for (const Case& c : cases) {
    const std::string path = dir + "/" + c.name;
    write_text(path, c.text);
    const std::string message = read_error(path);
    EXPECT_NE(message.find(dir + "/" + c.expect), std::string::npos)
        << c.name << ": got '" << message << "'";
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
  EXPECT_NE(read_error(dir + "/missing.ply").find("missing.ply: cannot open"), std::string::npos);
}

TEST(SurfaceFiles, WriteFailureLeavesNoFile) {
  const std::string dir = scratch_dir("surface_write_fail");
  EXPECT_THROW(write_surface(dir + "/nowhere/surface_000000.ply", cube(), SurfaceFormat::Ply),
               RuntimeError);
  EXPECT_FALSE(fs::exists(dir + "/nowhere"));
}

TEST(SurfaceFiles, SequenceListingAndPruning) {
  const std::string dir = scratch_dir("surface_sequence");
  for (const char* name : {"surface_000000.ply", "surface_000002.obj", "surface_000010.ply",
                           ".surface_000011.ply.tmp", "notes.txt", "surface_x.ply"})
    write_text(dir + "/" + name, "x");
  auto seq = list_surface_sequence(dir);
  ASSERT_EQ(seq.size(), 3u);
  EXPECT_EQ(seq[0].index, 0);
  EXPECT_EQ(seq[1].index, 2);
  EXPECT_EQ(seq[2].path, dir + "/surface_000010.ply");
  EXPECT_EQ(prune_surface_sequence(dir, 2), 2);  // frame 10 and the temporary
  EXPECT_TRUE(fs::exists(dir + "/surface_000002.obj"));
  EXPECT_TRUE(fs::exists(dir + "/notes.txt"));
  EXPECT_FALSE(fs::exists(dir + "/.surface_000011.ply.tmp"));
  EXPECT_EQ(prune_surface_sequence(dir, -1), 2);
  EXPECT_TRUE(list_surface_sequence(dir).empty());
  EXPECT_TRUE(list_surface_sequence(dir + "/absent").empty());
}

using test::load_png;
using test::Picture;

//! The object's orange material (red well above blue), as no background or ground is.
bool is_shaded(const std::array<std::uint8_t, 3>& c) {
  return c[0] > c[2] + 40 && c[0] > c[1];
}

int shaded_pixels(const Picture& p) {
  int count = 0;
  for (int y = 0; y < p.height; ++y)
    for (int x = 0; x < p.width; ++x) count += is_shaded(p.at(x, y));
  return count;
}

TEST(SurfacePreview, RendersShadedTrianglesWithOneCameraForTheSequence) {
  const std::string dir = scratch_dir("surface_preview");
  // Frame 0 at rest, frame 1 moved 3 units along x: the camera must frame both.
  write_surface(dir + "/surface_000000.ply", cube(0.0, false), SurfaceFormat::Ply);
  write_surface(dir + "/surface_000001.obj", cube(3.0, false), SurfaceFormat::Obj);
  const auto seq = list_surface_sequence(dir);
  ASSERT_EQ(seq.size(), 2u);
  const auto paths = render_surface_frames(seq, {0, 1}, dir, 160, 120, false);
  ASSERT_EQ(paths.size(), 2u);
  EXPECT_EQ(paths[1], dir + "/surface_000001.png");
  const Picture a = load_png(paths[0]), b = load_png(paths[1]);
  ASSERT_EQ(a.width, 160);
  ASSERT_EQ(a.height, 120);
  const int na = shaded_pixels(a), nb = shaded_pixels(b);
  EXPECT_GT(na, 100);
  EXPECT_GT(nb, 100);
  EXPECT_LT(na, 160 * 120 / 2);
  // Lambert shading: the visible faces get different brightness.
  std::set<std::array<std::uint8_t, 3>> shades;
  for (int y = 0; y < a.height; ++y)
    for (int x = 0; x < a.width; ++x)
      if (is_shaded(a.at(x, y))) shades.insert(a.at(x, y));
  EXPECT_GE(shades.size(), 2u);
  // Same camera, moved object: the images differ; the sky corner does not.
  EXPECT_NE(a.rgb, b.rgb);
  EXPECT_EQ(a.at(0, 0), b.at(0, 0));
  // The ground grid changes the lower part of the image, not the object's pixel count much.
  fs::create_directories(dir + "/ground");
  const auto grounded = render_surface_frames(seq, {0}, dir + "/ground", 160, 120, true);
  const Picture g = load_png(grounded[0]);
  EXPECT_NE(g.rgb, a.rgb);
  EXPECT_NEAR(shaded_pixels(g), na, na / 10 + 5);
  // A malformed file in the sequence is an InputError naming it.
  write_text(dir + "/surface_000002.ply", "ply\nformat ascii 1.0\n");
  EXPECT_THROW(render_surface_frames(list_surface_sequence(dir), {0}, dir, 32, 32, false),
               InputError);
}

}  // namespace
}  // namespace gen4d::io
