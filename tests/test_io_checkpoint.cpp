// Checkpoints at 1, 2 and 4 ranks: round trip of every field, restart at another
// decomposition and rank count, the keep-newest policy and write failures.
#include <gtest/gtest.h>

#include <filesystem>

#include "core/Error.hpp"
#include "io/Checkpoint.hpp"
#include "test_io_support.hpp"

namespace gen4d::io {
namespace {

using namespace iotest;

const std::array<long, 3> kDims{6, 3, 4};

//! A state owning the z slab of this rank, with fields of reference frame `frame`.
struct OwnedState {
  CheckpointState state;
  std::vector<double> x, v;
};

OwnedState make_state(int step, int frame) {
  OwnedState s;
  s.state.step = step;
  s.state.time = 0.001 * step + 1.0 / 7.0;
  s.state.frame_index = 3;
  s.state.next_frame_time = 0.125;
  // Longer than the 64 KiB limit of compact attribute storage.
  s.state.deck_text = "[simulation]\n" + std::string(100000, '#') + "\nend = 1\n";
  s.state.node_dims = kDims;
  s.state.owned = slab(kDims, 2, world_rank(), world_size());
  s.x = fill_box(s.state.owned, frame, position_value);
  s.v = fill_box(s.state.owned, frame, velocity_value);
  s.state.x = s.x.data();
  s.state.v = s.v.data();
  s.state.extras = {{"jacobi_omega", 0.66}, {"energy", -1.5e-3}, {"outer_iterations", 12}};
  return s;
}

TEST(Checkpoint, RoundTripAtAnotherDecomposition) {
  const std::string dir = scratch_dir("checkpoint_round_trip");
  OwnedState written = make_state(42, 5);
  const std::string path = write_checkpoint(MPI_COMM_WORLD, dir, written.state, 2);
  EXPECT_EQ(path, checkpoint_path(dir, 42));
  EXPECT_TRUE(std::filesystem::exists(dir + "/checkpoint_00000042.h5"));

  CheckpointMeta meta = read_checkpoint_meta(MPI_COMM_WORLD, path);
  EXPECT_EQ(meta.step, 42);
  EXPECT_EQ(meta.time, written.state.time);
  EXPECT_EQ(meta.frame_index, 3);
  EXPECT_EQ(meta.next_frame_time, 0.125);
  EXPECT_EQ(meta.deck_text, written.state.deck_text);
  EXPECT_EQ(meta.node_dims, kDims);
  EXPECT_EQ(meta.extras, written.state.extras);

  // Read back along x, a decomposition the writer did not use.
  const NodeBox along_x = slab(kDims, 0, world_rank(), world_size());
  std::vector<double> x, v;
  read_checkpoint_fields(MPI_COMM_WORLD, path, along_x, x, v);
  EXPECT_EQ(x, fill_box(along_x, 5, position_value));
  EXPECT_EQ(v, fill_box(along_x, 5, velocity_value));
}

TEST(Checkpoint, RestartsOnOtherRankCounts) {
  const std::string dir = scratch_dir("checkpoint_rank_counts");
  OwnedState written = make_state(7, 2);
  const std::string path = write_checkpoint(MPI_COMM_WORLD, dir, written.state, 0);

  // Every rank alone, as a 1-rank restart of the whole grid.
  std::vector<double> x, v;
  CheckpointMeta meta = read_checkpoint(MPI_COMM_SELF, path, whole(kDims), x, v);
  EXPECT_EQ(meta.step, 7);
  EXPECT_EQ(x, fill_box(whole(kDims), 2, position_value));
  EXPECT_EQ(v, fill_box(whole(kDims), 2, velocity_value));

  // Pairs of ranks, each pair splitting the grid along y.
  MPI_Comm pair;
  MPI_Comm_split(MPI_COMM_WORLD, world_rank() / 2, world_rank(), &pair);
  int rank = 0, size = 1;
  MPI_Comm_rank(pair, &rank);
  MPI_Comm_size(pair, &size);
  const NodeBox along_y = slab(kDims, 1, rank, size);
  read_checkpoint(pair, path, along_y, x, v);
  EXPECT_EQ(x, fill_box(along_y, 2, position_value));
  EXPECT_EQ(v, fill_box(along_y, 2, velocity_value));
  MPI_Comm_free(&pair);
}

TEST(Checkpoint, KeepsTheNewestAndLeavesNoTemporaries) {
  const std::string dir = scratch_dir("checkpoint_keep");
  EXPECT_EQ(latest_checkpoint(dir), "");
  EXPECT_EQ(latest_checkpoint(dir + "/absent"), "");
  for (int step : {100, 200, 300, 400}) {
    OwnedState s = make_state(step, step / 100);
    write_checkpoint(MPI_COMM_WORLD, dir, s.state, 2);
  }
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    names.push_back(entry.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, (std::vector<std::string>{"checkpoint_00000300.h5", "checkpoint_00000400.h5"}));
  EXPECT_EQ(latest_checkpoint(dir), checkpoint_path(dir, 400));
  MPI_Barrier(MPI_COMM_WORLD);  // nobody deletes while another rank still lists
}

TEST(Checkpoint, WriteFailureLeavesNothingBehind) {
  const std::string dir = scratch_dir("checkpoint_unwritable");
  const std::string not_a_dir = dir + "/plain_file";
  if (world_rank() == 0) std::ofstream(not_a_dir) << "occupied";
  MPI_Barrier(MPI_COMM_WORLD);
  OwnedState s = make_state(5, 0);
  EXPECT_THROW(write_checkpoint(MPI_COMM_WORLD, not_a_dir + "/ckpt", s.state, 2), RuntimeError);

  // A box outside the grid on one rank fails on all, before anything is created.
  s.state.owned.count[0] = world_rank() == world_size() - 1 ? kDims[0] + 1 : s.state.owned.count[0];
  EXPECT_THROW(write_checkpoint(MPI_COMM_WORLD, dir, s.state, 2), RuntimeError);
  MPI_Barrier(MPI_COMM_WORLD);
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    names.push_back(entry.path().filename().string());
  }
  EXPECT_EQ(names, std::vector<std::string>{"plain_file"});
}

}  // namespace
}  // namespace gen4d::io
