// Surface output of ElastoGen runs: the voxel boundary, embedded meshes (rest, affine and
// extrapolated vertices), independence of the rank count, restart, and deck validation.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>

#include "core/Error.hpp"
#include "elastogen/SurfaceEmbedding.hpp"
#include "deck_test_util.hpp"
#include "elastogen_test_util.hpp"
#include "io/Checkpoint.hpp"
#include "io/FrameReader.hpp"
#include "io/SurfaceIO.hpp"

using namespace gen4d;
namespace fs = std::filesystem;

namespace {

using test::scratch_dir;

//! A body clamped at x = 0 and pushed at its far end; the tests compare surfaces bit for bit
//! across rank counts.
std::string block_deck(const test::Keys& geometry) {
  return test::TestDeck()
      .simulation(0.01, 0.03)
      .domain(0.02)
      .table("[geometry]", geometry)
      .material(5.0e4, 0.3, 1000)
      .table("solver", {{"max_sweeps", "40"}})
      .clamp()
      .region("force", {0.07, -1, -1}, {1, 1, 1}, {{"force", "[0, 2, -4]"}})
      .table("output", {{"surface", test::quoted("ply")}, {"progress_interval", "1e9"}});
}
//! The body as a 5 x 4 x 3 voxel block.
const std::string kBlockDeck =
    block_deck({{"type", test::quoted("box")}, {"lo", "[0, 0, 0]"}, {"hi", "[0.1, 0.08, 0.06]"}});

Config block(const std::vector<std::string>& sets = {}) {
  return parse_deck(kBlockDeck, "<block>", ".", sets);
}

//! A closed box [0, 0.05] x [0, 0.03] x [0, 0.03] (file units) and a fin 0.002 thick beside
//! it that voxel centres miss at 0.02 m voxels with scale 2, so its vertices lie in empty
//! voxels up to 3 voxels from the solid.
const char* kBoxAndFinObj = R"(# box and fin
v 0 0 0
v 0.05 0 0
v 0 0.03 0
v 0.05 0.03 0
v 0 0 0.03
v 0.05 0 0.03
v 0 0.03 0.03
v 0.05 0.03 0.03
v 0.05 0.017 0
v 0.08 0.017 0
v 0.05 0.019 0
v 0.08 0.019 0
v 0.05 0.017 0.03
v 0.08 0.017 0.03
v 0.05 0.019 0.03
v 0.08 0.019 0.03
f 1 3 2
f 2 3 4
f 5 6 7
f 6 8 7
f 1 2 5
f 2 6 5
f 3 7 4
f 4 7 8
f 1 5 3
f 3 5 7
f 2 4 6
f 4 8 6
f 9 11 10
f 10 11 12
f 13 14 15
f 14 16 15
f 9 10 13
f 10 14 13
f 11 15 12
f 12 15 16
f 9 13 11
f 11 13 15
f 10 12 14
f 12 16 14
)";

//! Writes the box-and-fin OBJ to `dir` and returns a deck for it (scale 2, translated).
Config mesh_deck(const std::string& dir, const std::vector<std::string>& sets = {}) {
  const std::string obj = dir + "/box_fin.obj";
  if (test::world_rank() == 0) std::ofstream(obj) << kBoxAndFinObj;
  MPI_Barrier(MPI_COMM_WORLD);
  const std::string deck = block_deck({{"type", test::quoted("mesh")},
                                       {"file", test::quoted(obj)},
                                       {"scale", "2.0"},
                                       {"translate", "[0.01, -0.02, 0.03]"}});
  return parse_deck(deck, "<mesh>", ".", sets);
}

std::array<double, 3> affine(const std::array<double, 3>& p) {
  const double A[3][3] = {{1.1, 0.2, -0.1}, {0.05, 0.9, 0.3}, {-0.2, 0.1, 1.2}};
  const double b[3] = {0.3, -0.1, 0.05};
  std::array<double, 3> q{};
  for (int r = 0; r < 3; ++r) q[r] = A[r][0] * p[0] + A[r][1] * p[1] + A[r][2] * p[2] + b[r];
  return q;
}

using test::bytes_of;
using test::node_field;

TEST(Surface, VoxelBoundaryOfABoxIsClosedAndOutward) {
  elastogen::Simulation sim(MPI_COMM_WORLD, block());
  const elastogen::SurfaceEmbedding* s = sim.surface();
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->source(), elastogen::SurfaceSource::Voxels);
  // 2 (5*4 + 4*3 + 5*3) quads; the nodes of a 6x5x4 block minus its 4x3x2 interior.
  EXPECT_EQ(s->triangle_count(), 2 * 94);
  EXPECT_EQ(s->vertex_count(), 6 * 5 * 4 - 4 * 3 * 2);
  const auto rest = s->gather(sim.dynamics().x().data());
  const auto moved = s->gather(node_field(sim.system(), affine).data());
  if (test::world_rank() != 0) return;
  ASSERT_EQ(rest.size(), 3u * 96u);
  ASSERT_EQ(s->triangles().size(), 188u);
  // Watertight and consistently oriented: every directed edge once, and its reverse once.
  std::map<std::pair<int, int>, int> edges;
  for (const auto& t : s->triangles())
    for (int e = 0; e < 3; ++e) ++edges[{t[e], t[(e + 1) % 3]}];
  for (const auto& [edge, count] : edges) {
    EXPECT_EQ(count, 1);
    EXPECT_EQ(edges.count({edge.second, edge.first}), 1u);
  }
  EXPECT_EQ(edges.size(), 3u * 188u);
  // Outward: the enclosed signed volume is the box's.
  double volume = 0;
  for (const auto& t : s->triangles()) {
    const double* a = &rest[3 * t[0]];
    const double* b = &rest[3 * t[1]];
    const double* c = &rest[3 * t[2]];
    volume += (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
               a[2] * (b[0] * c[1] - b[1] * c[0])) /
              6.0;
  }
  EXPECT_NEAR(volume, 0.1 * 0.08 * 0.06, 1e-15);
  // Vertices are nodes: they take the node positions exactly.
  for (std::size_t v = 0; v < 96; ++v) {
    const auto q = affine({rest[3 * v], rest[3 * v + 1], rest[3 * v + 2]});
    for (int d = 0; d < 3; ++d) EXPECT_EQ(moved[3 * v + d], q[d]) << v;
  }
}

TEST(Surface, EmbeddedMeshReproducesRestAndAffineMotion) {
  const std::string dir = scratch_dir("surface_mesh_embed");
  elastogen::Simulation sim(MPI_COMM_WORLD, mesh_deck(dir));
  const elastogen::SurfaceEmbedding* s = sim.surface();
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->source(), elastogen::SurfaceSource::Mesh);
  EXPECT_EQ(s->vertex_count(), 16);
  EXPECT_EQ(s->triangle_count(), 24);
  // The fin's 8 vertices sit in empty voxels (plus box vertices on the far side of a grid
  // plane); the fin's tip is 3 voxels beyond the solid.
  EXPECT_GE(s->extrapolated_vertices(), 8);
  EXPECT_GT(s->max_extrapolation(), 2.9);
  EXPECT_LT(s->max_extrapolation(), 3.1);
  const auto rest = s->gather(sim.dynamics().x().data());
  const auto moved = s->gather(node_field(sim.system(), affine).data());
  if (test::world_rank() != 0) return;
  const geometry::Mesh file = geometry::read_obj(dir + "/box_fin.obj");
  ASSERT_EQ(rest.size(), 3 * file.vertices.size());
  const double t[3] = {0.01, -0.02, 0.03};
  double rest_err = 0, affine_err = 0;
  for (std::size_t v = 0; v < file.vertices.size(); ++v) {
    std::array<double, 3> p{};
    for (int d = 0; d < 3; ++d) p[d] = 2.0 * file.vertices[v][d] + t[d];
    const auto q = affine(p);
    for (int d = 0; d < 3; ++d) {
      rest_err = std::max(rest_err, std::fabs(rest[3 * v + d] - p[d]));
      affine_err = std::max(affine_err, std::fabs(moved[3 * v + d] - q[d]));
    }
  }
  EXPECT_LE(rest_err, 1e-12);
  EXPECT_LE(affine_err, 1e-12);
  ASSERT_EQ(s->triangles().size(), file.triangles.size());
  for (std::size_t f = 0; f < file.triangles.size(); ++f)
    for (int c = 0; c < 3; ++c) EXPECT_EQ(s->triangles()[f][c], file.triangles[f][c]);
}

TEST(Surface, RealMeshEmbeddingDoesNotDependOnTheDecomposition) {
  const std::string spot = std::string(GEN4D_SHARED_DIR) + "/data/meshes/spot.obj";
  if (!fs::exists(spot)) GTEST_SKIP() << spot << " not available";
  const std::string deck =
      block_deck({{"type", test::quoted("mesh")}, {"file", test::quoted(spot)}});
  const Config cfg = parse_deck(deck, "<spot>", ".", {"domain.voxel_size=0.1"});
  // A smooth non-affine motion: every vertex's 8 corners and weights matter.
  auto wave = [](const std::array<double, 3>& p) {
    return std::array<double, 3>{p[0] + 0.05 * std::sin(3 * p[1]), p[1] + 0.04 * std::cos(2 * p[2]),
                                 p[2] + 0.03 * std::sin(5 * p[0])};
  };
  elastogen::Simulation dist(MPI_COMM_WORLD, cfg);
  ASSERT_GT(dist.surface()->extrapolated_vertices(), 0);
  const auto xd = dist.surface()->gather(node_field(dist.system(), wave).data());
  const auto rd = dist.surface()->gather(dist.dynamics().x().data());
  if (test::world_rank() != 0) return;
  elastogen::Simulation serial(MPI_COMM_SELF, cfg);
  const auto xs = serial.surface()->gather(node_field(serial.system(), wave).data());
  ASSERT_EQ(xs.size(), xd.size());
  long differ = 0;
  for (std::size_t i = 0; i < xs.size(); ++i) differ += xs[i] != xd[i];
  EXPECT_EQ(differ, 0);
  const geometry::Mesh file = geometry::read_obj(spot);
  double err = 0;
  for (std::size_t v = 0; v < file.vertices.size(); ++v)
    for (int d = 0; d < 3; ++d) err = std::max(err, std::fabs(rd[3 * v + d] - file.vertices[v][d]));
  EXPECT_LE(err, 1e-12);
}

TEST(Surface, RunsWriteIdenticalFilesAtAnyRankCount) {
  const std::string dir = scratch_dir("surface_ranks");
  const std::vector<std::pair<std::string, Config>> decks = {
      {"voxels", block()}, {"mesh", mesh_deck(dir, {"output.surface=obj"})}};
  for (const auto& [name, cfg] : decks) {
    const std::string out = dir + "/" + name;
    {
      elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
      ASSERT_EQ(sim.run(out, false).exit_code, 0);
    }
    if (test::world_rank() != 0) continue;
    elastogen::Simulation serial(MPI_COMM_SELF, cfg);
    ASSERT_EQ(serial.run(out + "/serial", false).exit_code, 0);
    const auto files = io::list_surface_sequence(out + "/surface");
    const auto reference = io::list_surface_sequence(out + "/serial/surface");
    ASSERT_EQ(files.size(), 4u) << name;  // frames at steps 0..3
    ASSERT_EQ(reference.size(), files.size());
    for (std::size_t f = 0; f < files.size(); ++f) {
      EXPECT_EQ(files[f].index, static_cast<long>(f));
      EXPECT_EQ(bytes_of(files[f].path), bytes_of(reference[f].path)) << files[f].path;
    }
    // The last file holds the moved surface of the last frame.
    const io::SurfaceMesh last = io::read_surface(files.back().path);
    const io::SurfaceMesh first = io::read_surface(files.front().path);
    EXPECT_EQ(last.triangles, first.triangles);
    double moved = 0;
    for (std::size_t i = 0; i < last.xyz.size(); ++i)
      moved = std::max(moved, std::fabs(last.xyz[i] - first.xyz[i]));
    EXPECT_GT(moved, 1e-5) << name;
    ASSERT_FALSE(last.comments.empty());
    EXPECT_NE(last.comments[0].find("frame 3 step 3"), std::string::npos) << last.comments[0];
  }
}

TEST(Surface, RestartContinuesTheSequenceWithoutRewritingEarlierFrames) {
  const std::string dir = scratch_dir("surface_restart");
  const Config cfg =
      block({"simulation.end_time=0.06", "output.checkpoint_every=2", "output.checkpoint_keep=5"});
  {
    elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
    ASSERT_EQ(sim.run(dir, false).exit_code, 0);
  }
  const std::string sdir = dir + "/surface";
  std::vector<std::string> original;
  const auto past = fs::file_time_type::clock::now() - std::chrono::hours(24);
  if (test::world_rank() == 0) {
    const auto files = io::list_surface_sequence(sdir);
    ASSERT_EQ(files.size(), 7u);
    for (const auto& f : files) {
      original.push_back(bytes_of(f.path));
      fs::last_write_time(f.path, past);
    }
    std::ofstream(sdir + "/surface_000099.ply") << "stale";  // a frame the restart must drop
  }
  MPI_Barrier(MPI_COMM_WORLD);
  {
    elastogen::Simulation resumed(MPI_COMM_WORLD, cfg);
    resumed.load_checkpoint(io::checkpoint_path(dir, 2));
    ASSERT_EQ(resumed.run(dir, true).exit_code, 0);
  }
  if (test::world_rank() == 0) {
    const auto files = io::list_surface_sequence(sdir);
    ASSERT_EQ(files.size(), 7u);
    EXPECT_EQ(io::FrameReader(dir + "/frames.h5").frame_count(), 7);
    for (std::size_t f = 0; f < files.size(); ++f) {
      EXPECT_EQ(files[f].index, static_cast<long>(f));
      // Same rank count: the continued frames are bit-identical to the first run's.
      EXPECT_EQ(bytes_of(files[f].path), original[f]) << f;
      // Frames up to the restart step (0, 1, 2) are kept, later ones rewritten.
      EXPECT_EQ(fs::last_write_time(files[f].path) == past, f <= 2) << f;
    }
    EXPECT_FALSE(fs::exists(sdir + "/surface_000099.ply"));
    for (const auto& e : fs::directory_iterator(sdir))
      EXPECT_EQ(e.path().extension(), ".ply") << e.path();
    std::ofstream(sdir + "/surface_000050.obj") << "stale";
  }
  MPI_Barrier(MPI_COMM_WORLD);
  // A fresh run into the same folder replaces the whole sequence.
  {
    elastogen::Simulation again(MPI_COMM_WORLD, block());
    ASSERT_EQ(again.run(dir, false).exit_code, 0);
  }
  if (test::world_rank() == 0) {
    EXPECT_EQ(io::list_surface_sequence(sdir).size(), 4u);
    EXPECT_FALSE(fs::exists(sdir + "/surface_000050.obj"));
  }
}

TEST(Surface, DeckKeysAreValidatedWithTheirLocation) {
  auto error_of = [](const std::string& text) {
    try {
      parse_deck(text, "deck.toml", ".");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  std::string deck = kBlockDeck;
  const std::string key = "surface = \"ply\"";
  const auto at = deck.find(key);
  const long line = 1 + std::count(deck.begin(), deck.begin() + at, '\n');
  const std::string format =
      error_of(std::string(deck).replace(at, key.size(), "surface = \"stl\""));
  EXPECT_EQ(format.rfind("deck.toml:" + std::to_string(line) +
                             ": key 'output.surface': must be one of none, ply, obj, got 'stl'",
                         0),
            0u)
      << format;
  const std::string source = error_of(
      std::string(deck).replace(at, key.size(), "surface = \"ply\"\nsurface_source = \"mesh\""));
  EXPECT_EQ(source.rfind("deck.toml:" + std::to_string(line + 1) +
                             ": key 'output.surface_source': \"mesh\" needs every [[geometry]]",
                         0),
            0u)
      << source;
  EXPECT_EQ(block({"output.surface=obj"}).output.surface, "obj");
  EXPECT_EQ(block({"output.surface_source=voxels"}).output.surface_source, "voxels");
  EXPECT_EQ(parse_deck(std::string(deck).replace(at, key.size(), ""), "d", ".").output.surface,
            "none");
}

}  // namespace
