// Frames file round trips at 1, 2 and 4 ranks: bit-exact datasets for any decomposition, the
// XDMF index, and appending after a restart.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <regex>

#include "core/Error.hpp"
#include "io/FrameReader.hpp"
#include "io/FrameWriter.hpp"
#include "test_io_support.hpp"

namespace gen4d::io {
namespace {

using namespace iotest;

// nz = 3 nodes and 2 cells along z: at 4 ranks some z slabs are empty.
const std::array<long, 3> kDims{5, 4, 3};

GridMeta grid_meta() {
  GridMeta meta;
  meta.node_dims = kDims;
  meta.origin = {-1.0, -1.0, -1.0};
  meta.spacing = 0.1;
  meta.attributes = {{"deck", "[simulation]\nname = \"cube\"\n"},
                     {"version", "0.1.0"},
                     {"ranks", std::to_string(world_size())}};
  return meta;
}

void write_occupancy(FrameWriter& writer, int axis) {
  const CellBox cells = slab(cell_dims(kDims), axis, world_rank(), world_size());
  std::vector<std::uint8_t> occ;
  for (long k = cells.start[2]; k < cells.start[2] + cells.count[2]; ++k)
    for (long j = cells.start[1]; j < cells.start[1] + cells.count[1]; ++j)
      for (long i = cells.start[0]; i < cells.start[0] + cells.count[0]; ++i)
        occ.push_back(occupancy_value(i, j, k));
  writer.write_occupancy(cells, cells.empty() ? nullptr : occ.data());
}

void write_frame(FrameWriter& writer, int frame, double time, int step, int axis) {
  const NodeBox nodes = slab(kDims, axis, world_rank(), world_size());
  std::vector<double> x = fill_box(nodes, frame, position_value);
  std::vector<double> v = fill_box(nodes, frame, velocity_value);
  writer.write_frame(time, step, nodes, nodes.empty() ? nullptr : x.data(),
                     nodes.empty() ? nullptr : v.data());
}

void expect_frame(const FrameReader& reader, int n, int frame) {
  EXPECT_EQ(reader.read_position(n), fill_box(whole(kDims), frame, position_value));
  EXPECT_EQ(reader.read_velocity(n), fill_box(whole(kDims), frame, velocity_value));
}

//! Checks tag nesting of XML text, skipping declarations; returns the root element's name.
std::string xml_root(const std::string& text) {
  std::vector<std::string> open;
  std::string root;
  for (std::size_t pos = text.find('<'); pos != std::string::npos; pos = text.find('<', pos)) {
    const std::size_t end = text.find('>', pos);
    if (end == std::string::npos) return "";
    const std::string tag = text.substr(pos + 1, end - pos - 1);
    pos = end + 1;
    if (tag.empty() || tag[0] == '?' || tag[0] == '!') continue;
    if (std::count(tag.begin(), tag.end(), '"') % 2 != 0) return "";
    const bool closing = tag[0] == '/', self_closing = tag.back() == '/';
    const std::string name = tag.substr(closing, tag.find_first_of(" />", closing) - closing);
    if (closing) {
      if (open.empty() || open.back() != name) return "";
      open.pop_back();
    } else if (!self_closing) {
      if (open.empty() && !root.empty()) return "";  // a second root element
      if (open.empty()) root = name;
      open.push_back(name);
    }
  }
  return open.empty() ? root : "";
}

std::vector<double> xdmf_times(const std::string& text) {
  std::vector<double> times;
  std::regex time_tag("<Time Value=\"([^\"]+)\"");
  for (std::sregex_iterator it(text.begin(), text.end(), time_tag), end; it != end; ++it) {
    times.push_back(std::stod((*it)[1]));
  }
  return times;
}

TEST(FrameFile, RoundTripIsBitExactAndIndexed) {
  const std::string dir = scratch_dir("frames_round_trip");
  const std::string path = dir + "/run.h5";
  const std::vector<double> times{0.0, 0.1, 1.0 / 3.0};
  {
    FrameWriter writer(MPI_COMM_WORLD, path, grid_meta());
    write_occupancy(writer, 2);
    for (int f = 0; f < 3; ++f) write_frame(writer, f, times[f], 10 * f, 2);
    EXPECT_EQ(writer.xdmf_path(), dir + "/run.xdmf");
    writer.close();
  }
  MPI_Barrier(MPI_COMM_WORLD);
  FrameReader reader(path);
  EXPECT_EQ(reader.node_dims(), kDims);
  EXPECT_EQ(reader.meta().origin, grid_meta().origin);
  EXPECT_EQ(reader.meta().spacing, 0.1);
  for (const auto& [key, value] : grid_meta().attributes) {
    EXPECT_EQ(reader.attributes().at(key), value) << key;
  }
  ASSERT_EQ(reader.frame_count(), 3);
  for (int f = 0; f < 3; ++f) {
    EXPECT_EQ(reader.frames()[f].time, times[f]);
    EXPECT_EQ(reader.frames()[f].step, 10 * f);
    expect_frame(reader, f, f);
  }
  std::vector<std::uint8_t> occ;
  const auto cells = cell_dims(kDims);
  for (long k = 0; k < cells[2]; ++k)
    for (long j = 0; j < cells[1]; ++j)
      for (long i = 0; i < cells[0]; ++i) occ.push_back(occupancy_value(i, j, k));
  EXPECT_EQ(reader.read_occupancy(), occ);

  const std::string xdmf = file_bytes(dir + "/run.xdmf");
  EXPECT_EQ(xml_root(xdmf), "Xdmf");
  EXPECT_EQ(xdmf_times(xdmf), times);
  for (const char* needle :
       {"CollectionType=\"Temporal\"", "TopologyType=\"3DSMesh\" Dimensions=\"3 4 5\"",
        "GeometryType=\"XYZ\"", "run.h5:/frames/000002/position", "run.h5:/frames/000002/velocity",
        "run.h5:/occupancy", "Center=\"Cell\"", "Dimensions=\"2 3 4\""}) {
    EXPECT_NE(xdmf.find(needle), std::string::npos) << needle;
  }
  EXPECT_FALSE(std::filesystem::exists(dir + "/run.xdmf.tmp"));
}

TEST(FrameFile, DecompositionsWriteIdenticalFiles) {
  const std::string dir = scratch_dir("frames_decomposition");
  for (int axis : {0, 2}) {
    FrameWriter writer(MPI_COMM_WORLD, dir + "/axis" + std::to_string(axis) + ".h5", grid_meta());
    write_occupancy(writer, axis);
    write_frame(writer, 4, 0.5, 7, axis);
    writer.close();
  }
  MPI_Barrier(MPI_COMM_WORLD);
  FrameReader along_x(dir + "/axis0.h5"), along_z(dir + "/axis2.h5");
  EXPECT_EQ(along_x.read_position(0), along_z.read_position(0));
  EXPECT_EQ(along_x.read_velocity(0), along_z.read_velocity(0));
  EXPECT_EQ(along_x.read_occupancy(), along_z.read_occupancy());
  expect_frame(along_x, 0, 4);
}

TEST(FrameFile, AppendAfterRestartDropsLaterFrames) {
  const std::string dir = scratch_dir("frames_append");
  const std::string path = dir + "/run.h5";
  {
    FrameWriter writer(MPI_COMM_WORLD, path, grid_meta());
    write_occupancy(writer, 2);
    for (int f = 0; f < 3; ++f) write_frame(writer, f, 0.1 * (f + 1), 10 * (f + 1), 2);
  }
  {
    FrameWriter writer = FrameWriter::open_append(MPI_COMM_WORLD, path, 20);
    ASSERT_EQ(writer.frames().size(), 2u);
    EXPECT_EQ(writer.frames().back().step, 20);
    write_frame(writer, 9, 0.25, 25, 0);
    writer.close();
  }
  MPI_Barrier(MPI_COMM_WORLD);
  FrameReader reader(path);
  ASSERT_EQ(reader.frame_count(), 3);
  EXPECT_EQ(reader.frames()[2].step, 25);
  EXPECT_EQ(reader.frames()[2].time, 0.25);
  expect_frame(reader, 1, 1);
  expect_frame(reader, 2, 9);
  EXPECT_EQ(xdmf_times(file_bytes(dir + "/run.xdmf")), (std::vector<double>{0.1, 0.2, 0.25}));
}

TEST(FrameFile, UnwritableLocationIsARuntimeErrorOnEveryRank) {
  const std::string dir = scratch_dir("frames_unwritable");
  const std::string path = dir + "/missing_folder/run.h5";
  EXPECT_THROW(FrameWriter(MPI_COMM_WORLD, path, grid_meta()), RuntimeError);
  EXPECT_FALSE(std::filesystem::exists(path));
}

TEST(FrameFile, BoxOutsideTheGridIsRejectedOnEveryRank) {
  const std::string dir = scratch_dir("frames_bad_box");
  FrameWriter writer(MPI_COMM_WORLD, dir + "/run.h5", grid_meta());
  NodeBox nodes = slab(kDims, 2, world_rank(), world_size());
  if (world_rank() == world_size() - 1) nodes.count[0] += 1;  // one rank is wrong
  std::vector<double> x(3 * nodes.size(), 0.0);
  EXPECT_THROW(writer.write_frame(0.0, 0, nodes, x.data(), x.data()), RuntimeError);
  EXPECT_TRUE(writer.frames().empty());
}

}  // namespace
}  // namespace gen4d::io
