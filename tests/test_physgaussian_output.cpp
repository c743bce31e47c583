// PhysGaussian's output layout: gs_simulation.py's image names, the [render] scenery drawn with
// every frame (bit for bit at 1, 2 and 4 ranks), frames merged without changing a colour, and
// the --output_ply particle files.
#include <gtest/gtest.h>
#include <mpi.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "core/Config.hpp"
#include "core/Error.hpp"
#include "gaussians/Camera.hpp"
#include "gaussians/Kinematics.hpp"
#include "gaussians/PhysGaussianOutput.hpp"
#include "gaussians/Ply.hpp"
#include "gaussians/Render.hpp"
#include "gaussians/RunRender.hpp"
#include "mpi_test_util.hpp"

namespace gen4d::gaussians {
namespace {

namespace fs = std::filesystem;

using test::rank_of;
using test::size_of;

//! A scratch folder shared by the ranks of this run (rank 0 empties it).
fs::path shared_scratch(const std::string& name) {
  return test::scratch_dir("physgaussian_output/" + name);
}

std::string bytes(const fs::path& p) {
  return test::bytes_of(p.string());
}

//! `n` splats in front of a camera at the origin looking along +z, SH degree `degree` with
//! non-zero coefficients, deterministic pseudo-random values from `seed`.
SplatSet splats(int n, int degree, unsigned seed, double z0) {
  SplatSet s;
  s.sh_degree = degree;
  unsigned state = seed;
  auto next = [&] {
    state = state * 1664525u + 1013904223u;
    return static_cast<double>(state >> 8) / static_cast<double>(1u << 24);
  };
  const int K = sh_coefficients(degree);
  for (int i = 0; i < n; ++i) {
    s.position.insert(s.position.end(), {next() - 0.5, next() - 0.5, z0 + next()});
    s.scale.insert(s.scale.end(), {0.05 + 0.1 * next(), 0.05 + 0.1 * next(), 0.02 + 0.05 * next()});
    const double a = 3 * next();
    s.rotation.insert(s.rotation.end(), {std::cos(a), 0.6 * std::sin(a), 0.8 * std::sin(a), 0});
    s.opacity.push_back(0.3 + 0.6 * next());
    for (int k = 0; k < 3 * K; ++k) s.sh.push_back(k < 3 ? next() - 0.3 : 0.4 * (next() - 0.5));
  }
  return s;
}

//! The splats i with i % size == rank as a deformed frame: harmonics rotated by 30 degrees
//! about z (sh_rotation), as the solvers hand them to the renderer.
SplatFrame share(const SplatSet& all, int rank, int size) {
  SplatFrame f = rest_frame(all);
  SplatFrame mine;
  mine.sh_degree = f.sh_degree;
  const int K = f.coefficients();
  const float c = std::cos(0.5236f), s = std::sin(0.5236f);
  for (std::size_t i = 0; i < f.size(); ++i) {
    if (static_cast<int>(i % static_cast<std::size_t>(size)) != rank) continue;
    mine.position.insert(mine.position.end(), &f.position[3 * i], &f.position[3 * i + 3]);
    mine.covariance.insert(mine.covariance.end(), &f.covariance[6 * i], &f.covariance[6 * i + 6]);
    mine.opacity.push_back(f.opacity[i]);
    mine.sh.insert(mine.sh.end(), &f.sh[3 * K * i], &f.sh[3 * K * (i + 1)]);
    mine.sh_rotation.insert(mine.sh_rotation.end(), {c, -s, 0, s, c, 0, 0, 0, 1});
  }
  return mine;
}

Camera front_camera() {
  Camera c;
  c.width = 72;
  c.height = 56;
  c.fx = c.fy = 60;
  return c;
}

TEST(PhysGaussianOutput, ImageNamesAsGsSimulation) {
  // f"{frame}.png".rjust(8, "0")
  EXPECT_EQ(physgaussian_png_name(0), "0000.png");
  EXPECT_EQ(physgaussian_png_name(42), "0042.png");
  EXPECT_EQ(physgaussian_png_name(9999), "9999.png");
  EXPECT_EQ(physgaussian_png_name(10000), "10000.png");
  EXPECT_EQ(physgaussian_png_index("0042.png"), 42);
  EXPECT_EQ(physgaussian_png_index("10000.png"), 10000);
  for (const char* other : {"00042.png", "042.png", "frame_000001.png", "0042.PNG", "00a1.png"})
    EXPECT_EQ(physgaussian_png_index(other), -1) << other;
  // Image k shows the state after k + 1 frames; frame 0 (rest) has none.
  EXPECT_EQ(frame_image_name("physgaussian", 0), "");
  EXPECT_EQ(frame_image_name("physgaussian", 1), "0000.png");
  EXPECT_EQ(frame_image_name("physgaussian", 125), "0124.png");
  EXPECT_EQ(frame_image_index("physgaussian", "0124.png"), 125);
  EXPECT_EQ(frame_image_index("physgaussian", "png/0124.png"), -1);
  EXPECT_EQ(frame_image_name("gen4d", 0), "png/frame_000000.png");
  EXPECT_EQ(frame_image_index("gen4d", "png/frame_000007.png"), 7);
  EXPECT_EQ(frame_image_index("gen4d", "0007.png"), -1);
  EXPECT_EQ(simulation_ply_name(3), "simulation_ply/sim_0000000003.ply");
}

TEST(PhysGaussianOutput, MergingFramesKeepsEveryColour) {
  // Scenery of SH degree 0 without sh_rotation, alone and merged with a degree-3 frame with
  // sh_rotation that the camera culls (behind it): the images are bit-identical.
  const SplatFrame scenery = rest_frame(splats(40, 0, 7, 2.0));
  SplatFrame behind = share(splats(5, 3, 11, -4.0), 0, 1);
  const SplatFrame merged = merge_frames(behind, scenery);
  ASSERT_EQ(merged.size(), 45u);
  EXPECT_EQ(merged.sh_degree, 3);
  EXPECT_EQ(merged.sh_rotation.size(), 9u * 45);
  EXPECT_EQ(merged.sh.size(), 3u * 16 * 45);
  const Image a = render(scenery, front_camera()), b = render(merged, front_camera());
  EXPECT_EQ(a.rgb, b.rgb);
  // The same splats drawn: the merged frame of the scenery alone is the scenery.
  EXPECT_EQ(merge_frames(SplatFrame{}, scenery).position, scenery.position);
}

TEST(PhysGaussianOutput, SceneryDrawnInEveryFrameAtAnyRankCount) {
  MPI_Comm comm = MPI_COMM_WORLD;
  const int rank = rank_of(comm), size = size_of(comm);
  const fs::path dir = shared_scratch("scenery");
  const SplatSet object = splats(60, 1, 3, 2.5), scenery = splats(80, 0, 5, 2.0);
  if (rank == 0) {
    write_splats_ply((dir / "scenery.ply").string(), scenery);
    write_cameras_json((dir / "cameras.json").string(), {front_camera()});
  }
  MPI_Barrier(comm);
  RenderConfig r;
  r.enabled = true;
  r.camera = (dir / "cameras.json").string();
  r.background = {0, 0, 0};
  r.layout = "physgaussian";
  r.scenery = (dir / "scenery.ply").string();
  const fs::path out = dir / "out";
  RunRenderer renderer(comm, r);
  renderer.open(out.string(), -1);
  const SplatFrame local = share(object, rank, size);
  renderer.render(0, local);  // the rest state: no image under this layout
  renderer.render(1, local);
  renderer.render(2, SplatFrame{});  // no object splats left: the scenery alone
  EXPECT_EQ(renderer.images(), 2);
  if (rank == 0) {
    EXPECT_FALSE(fs::exists(out / "png"));
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(out)) names.push_back(e.path().filename());
    std::sort(names.begin(), names.end());
    EXPECT_EQ(names, (std::vector<std::string>{"0000.png", "0001.png"}));
    // References: one process drawing everything; the rest frame of the scenery as read back.
    const SplatFrame scenery_frame = rest_frame(read_splats_ply(r.scenery));
    const SplatFrame all = merge_frames(share(object, 0, 1), scenery_frame);
    write_image_png((dir / "with.png").string(), render(all, front_camera()));
    write_image_png((dir / "alone.png").string(), render(scenery_frame, front_camera()));
    write_image_png((dir / "without.png").string(), render(share(object, 0, 1), front_camera()));
    EXPECT_EQ(bytes(out / "0000.png"), bytes(dir / "with.png"));
    EXPECT_EQ(bytes(out / "0001.png"), bytes(dir / "alone.png"));
    EXPECT_NE(bytes(out / "0000.png"), bytes(dir / "without.png"));  // the scenery shows
  }
}

TEST(PhysGaussianOutput, OpenRemovesOnlyTheLayoutsLaterImages) {
  MPI_Comm comm = MPI_COMM_WORLD;
  const fs::path dir = shared_scratch("open");
  const std::vector<std::string> files = {"0000.png",    "0002.png",         "0005.png",
                                          "00001.png",   "frame_000009.png", "notes.png",
                                          "particles.h5"};
  if (rank_of(comm) == 0)
    for (const auto& f : files) std::ofstream(dir / f) << "x";
  MPI_Barrier(comm);
  RenderConfig r;
  r.enabled = true;
  r.layout = "physgaussian";
  RunRenderer renderer(comm, r);
  renderer.open(dir.string(), 3);  // a restart keeping frames 0..3: images 0000..0002
  EXPECT_EQ(renderer.png_dir(), dir.string());
  if (rank_of(comm) == 0)
    for (const auto& f : files) EXPECT_EQ(fs::exists(dir / f), f != "0005.png") << f;
  MPI_Barrier(comm);
}

TEST(PhysGaussianOutput, ParticlePlyAsPhysGaussianWritesIt) {
  const fs::path dir = shared_scratch("ply") / ("r" + std::to_string(rank_of(MPI_COMM_WORLD)));
  fs::create_directories(dir);
  const std::vector<double> xyz = {0.5, 1.25, -2, 1e-3, 3, 4.5};
  const std::string path = (dir / "sim_0000000000.ply").string();
  write_positions_ply(path, xyz);
  const std::string text = bytes(path);
  const std::string header =
      "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\n"
      "property float y\nproperty float z\nend_header\n";
  ASSERT_EQ(text.substr(0, header.size()), header);
  EXPECT_EQ(text.size(), header.size() + 2 * 12);
  const std::vector<float> back = read_positions_ply(path);
  ASSERT_EQ(back.size(), 6u);
  for (std::size_t i = 0; i < 6; ++i) EXPECT_EQ(back[i], static_cast<float>(xyz[i]));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
  // A truncated body and a file with more properties are InputErrors naming the file.
  std::ofstream(dir / "short.ply", std::ios::binary) << text.substr(0, text.size() - 1);
  std::ofstream(dir / "splat.ply", std::ios::binary)
      << "ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\n"
         "property float y\nproperty float z\nproperty float opacity\nend_header\n";
  for (const char* bad : {"short.ply", "splat.ply"}) {
    try {
      read_positions_ply((dir / bad).string());
      ADD_FAILURE() << bad << " accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace gen4d::gaussians
