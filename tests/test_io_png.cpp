// PNG previews: size, content, a fixed camera across frames, and clean failures.
#include <gtest/gtest.h>
#include <png.h>

#include <filesystem>

#include "core/Error.hpp"
#include "io/FrameWriter.hpp"
#include "io/PngPreview.hpp"
#include "png_test_util.hpp"
#include "test_io_support.hpp"

namespace gen4d::io {
namespace {

using namespace iotest;

const std::array<long, 3> kDims{7, 6, 5};

using test::load_png;
using test::Picture;

//! Pixels unlike the background, which the leftmost column shows (the solid sits centred).
int object_pixels(const Picture& p) {
  int count = 0;
  for (int y = 0; y < p.height; ++y) {
    for (int x = 1; x < p.width; ++x) count += p.at(x, y) != p.at(0, y);
  }
  return count;
}

//! A box of 6x5x4 voxels missing one corner voxel: frame 0 at rest, frame 1 sheared along x.
std::string write_box_frames(const std::string& dir) {
  GridMeta meta;
  meta.node_dims = kDims;
  meta.spacing = 0.1;
  const std::string path = dir + "/box.h5";
  FrameWriter writer(MPI_COMM_SELF, path, meta);
  const auto cells = cell_dims(kDims);
  std::vector<std::uint8_t> occ(cells[0] * cells[1] * cells[2], 1);
  occ.back() = 0;
  writer.write_occupancy(whole(cells), occ.data());
  for (int frame = 0; frame < 2; ++frame) {
    auto x = fill_box(whole(kDims), frame, [](long i, long j, long k, int c, int f) {
      const double rest[3] = {0.1 * i, 0.1 * j, 0.1 * k};
      return rest[c] + (c == 0 ? 0.08 * f * k : 0.0);
    });
    std::vector<double> v(x.size(), 0.0);
    writer.write_frame(0.1 * frame, frame, whole(kDims), x.data(), v.data());
  }
  writer.close();
  return path;
}

TEST(PngPreview, RendersTheSurfaceAtTheRequestedSize) {
  const std::string dir = scratch_dir("png_preview");
  FrameReader reader(write_box_frames(dir));
  const std::string png = dir + "/rest.png";
  render_frame_png(reader, 0, png, 160, 120);
  const Picture rest = load_png(png);
  ASSERT_EQ(rest.width, 160);
  ASSERT_EQ(rest.height, 120);
  const int covered = object_pixels(rest);
  EXPECT_GT(covered, 160 * 120 / 10);  // the box fills a good part of the frame
  EXPECT_LT(covered, 160 * 120 * 9 / 10);
  EXPECT_FALSE(std::filesystem::exists(png + ".tmp"));

  const std::vector<std::string> paths = render_frames(reader, {0, 1}, dir, 64, 48);
  ASSERT_EQ(paths.size(), 2u);
  EXPECT_EQ(paths[1], dir + "/frame_000001.png");
  const Picture a = load_png(paths[0]), b = load_png(paths[1]);
  EXPECT_EQ(a.width, 64);
  EXPECT_EQ(b.height, 48);
  EXPECT_NE(a.rgb, b.rgb);  // the shear shows with the same camera
  EXPECT_EQ(a.at(0, 0), b.at(0, 0));
}

TEST(PngPreview, FailuresLeaveNoFile) {
  const std::string dir = scratch_dir("png_failures");
  FrameReader reader(write_box_frames(dir));
  const std::string png = dir + "/missing_folder/frame.png";
  EXPECT_THROW(render_frame_png(reader, 0, png, 32, 32), RuntimeError);
  EXPECT_FALSE(std::filesystem::exists(dir + "/missing_folder"));
  EXPECT_THROW(render_frame_png(reader, 5, dir + "/f.png", 32, 32), InputError);
  EXPECT_THROW(render_frame_png(reader, 0, dir + "/f.png", 0, 32), InputError);
  EXPECT_FALSE(std::filesystem::exists(dir + "/f.png"));
}

}  // namespace
}  // namespace gen4d::io
