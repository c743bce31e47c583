// Damaged, foreign and mismatched files must give one InputError line naming the file and the
// problem, on every rank, and must never be modified by the reader.
#include <gtest/gtest.h>
#include <hdf5.h>

#include "core/Error.hpp"
#include "io/Checkpoint.hpp"
#include "io/FrameReader.hpp"
#include "io/FrameWriter.hpp"
#include "test_io_support.hpp"

namespace gen4d::io {
namespace {

using namespace iotest;

const std::array<long, 3> kDims{4, 3, 3};

struct BadFiles : ::testing::Test {
  std::string dir;
  std::string good_checkpoint, frames;

  void SetUp() override {
    dir = scratch_dir("bad_files");
    CheckpointState state;
    state.step = 3;
    state.deck_text = "[simulation]";
    state.node_dims = kDims;
    state.owned = slab(kDims, 2, world_rank(), world_size());
    std::vector<double> x = fill_box(state.owned, 0, position_value);
    state.x = state.v = x.data();
    good_checkpoint = write_checkpoint(MPI_COMM_WORLD, dir, state, 0);

    frames = dir + "/frames.h5";
    GridMeta meta;
    meta.node_dims = kDims;
    FrameWriter writer(MPI_COMM_WORLD, frames, meta);
    writer.write_frame(0.0, 0, state.owned, state.x, state.v);
    writer.write_frame(0.5, 1, state.owned, state.x, state.v);
  }

  // Serial reads in a test must finish before the next test's SetUp empties the folder.
  void TearDown() override { MPI_Barrier(MPI_COMM_WORLD); }

  //! Runs `make` on rank 0 to produce dir/name, then shares the path with every rank.
  template <class Make>
  std::string prepare(const std::string& name, Make make) {
    const std::string path = dir + "/" + name;
    if (world_rank() == 0) make(path);
    MPI_Barrier(MPI_COMM_WORLD);
    return path;
  }

  //! Copies the good checkpoint and edits the copy with the plain HDF5 API.
  template <class Edit>
  std::string edited_checkpoint(const std::string& name, Edit edit) {
    return prepare(name, [&](const std::string& path) {
      std::filesystem::copy_file(good_checkpoint, path);
      hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
      ASSERT_GE(file, 0);
      edit(file);
      H5Fclose(file);
    });
  }
};

//! Expects an InputError on every rank whose message names `path` and contains `problem`,
//! and that the file is unchanged.
template <class Read>
void expect_input_error(const std::string& path, const std::string& problem, Read read) {
  const std::string before = file_bytes(path);
  try {
    read();
    ADD_FAILURE() << "no InputError for " << path;
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find(path), std::string::npos) << message;
    EXPECT_NE(message.find(problem), std::string::npos) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
  EXPECT_EQ(file_bytes(path), before);
}

void expect_bad_checkpoint(const std::string& path, const std::string& problem) {
  expect_input_error(path, problem, [&] { read_checkpoint_meta(MPI_COMM_WORLD, path); });
  std::vector<double> x, v;
  expect_input_error(path, problem, [&] {
    read_checkpoint_fields(MPI_COMM_WORLD, path, slab(kDims, 0, world_rank(), world_size()), x, v);
  });
}

TEST_F(BadFiles, TextFile) {
  const std::string path =
      prepare("notes.h5", [](const std::string& p) { std::ofstream(p) << "not hdf5 at all\n"; });
  expect_bad_checkpoint(path, "not an HDF5 file");
  expect_input_error(path, "not an HDF5 file", [&] { FrameReader reader(path); });
}

TEST_F(BadFiles, MissingFile) {
  const std::string path = dir + "/nowhere.h5";
  expect_bad_checkpoint(path, "no such file");
  expect_input_error(path, "no such file", [&] { FrameReader reader(path); });
  EXPECT_FALSE(std::filesystem::exists(path));
}

TEST_F(BadFiles, TruncatedCheckpoint) {
  const std::string path = prepare("truncated.h5", [&](const std::string& p) {
    const std::string bytes = file_bytes(good_checkpoint);
    std::ofstream(p, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  });
  expect_bad_checkpoint(path, "truncated");
}

TEST_F(BadFiles, ForeignHdf5File) {
  const std::string path = prepare("foreign.h5", [](const std::string& p) {
    hid_t file = H5Fcreate(p.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    hsize_t n = 8;
    hid_t space = H5Screate_simple(1, &n, nullptr);
    hid_t data =
        H5Dcreate2(file, "random", H5T_NATIVE_DOUBLE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    double values[8] = {0.3, 0.1, 0.4, 0.1, 0.5, 0.9, 0.2, 0.6};
    H5Dwrite(data, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values);
    H5Dclose(data);
    H5Sclose(space);
    H5Fclose(file);
  });
  expect_bad_checkpoint(path, "not a gen4d checkpoint (no 'format' attribute)");
  expect_input_error(path, "not a gen4d frames file", [&] { FrameReader reader(path); });
}

TEST_F(BadFiles, FramesFilePassedAsCheckpoint) {
  expect_bad_checkpoint(frames, "format is 'gen4d-frames', expected 'gen4d-checkpoint'");
  expect_input_error(good_checkpoint, "format is 'gen4d-checkpoint'",
                     [&] { FrameReader reader(good_checkpoint); });
}

TEST_F(BadFiles, WrongFormatVersion) {
  const std::string path = edited_checkpoint("version2.h5", [](hid_t file) {
    long version = 2;
    hid_t attr = H5Aopen(file, "format_version", H5P_DEFAULT);
    H5Awrite(attr, H5T_NATIVE_LONG, &version);
    H5Aclose(attr);
  });
  expect_bad_checkpoint(path, "format_version 2 is not supported");
}

TEST_F(BadFiles, MissingDataset) {
  const std::string path = edited_checkpoint(
      "no_velocity.h5", [](hid_t file) { H5Ldelete(file, "/velocity", H5P_DEFAULT); });
  expect_bad_checkpoint(path, "missing dataset /velocity");
}

TEST_F(BadFiles, MisshapedDataset) {
  const std::string path = edited_checkpoint("misshaped.h5", [](hid_t file) {
    long dims[3] = {4, 3, 2};
    hid_t attr = H5Aopen(file, "node_dims", H5P_DEFAULT);
    H5Awrite(attr, H5T_NATIVE_LONG, dims);
    H5Aclose(attr);
  });
  expect_bad_checkpoint(path, "dataset /position has shape [3 3 4 3], expected [2 3 4 3]");
}

TEST_F(BadFiles, FrameMissingItsVelocity) {
  const std::string path = prepare("frames_damaged.h5", [&](const std::string& p) {
    std::filesystem::copy_file(frames, p);
    hid_t file = H5Fopen(p.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    H5Ldelete(file, (frame_group(1) + "/velocity").c_str(), H5P_DEFAULT);
    H5Fclose(file);
  });
  FrameReader reader(path);
  EXPECT_EQ(reader.read_velocity(0).size(), 3u * 4 * 3 * 3);
  expect_input_error(path, "missing dataset " + frame_group(1) + "/velocity",
                     [&] { reader.read_velocity(1); });
  expect_input_error(path, "missing dataset /occupancy", [&] { reader.read_occupancy(); });
  expect_input_error(path, "no frame 2", [&] { reader.read_position(2); });
}

}  // namespace
}  // namespace gen4d::io
