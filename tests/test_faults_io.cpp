// Faults of the write path at 1 and 2 ranks: a checkpoint temporary left by a killed run is
// never taken for a checkpoint and is removed by the next checkpoint write; a failed write
// names its cause (no space, file size limit).
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <filesystem>
#include <fstream>

#include "io/AtomicFile.hpp"
#include "io/Checkpoint.hpp"
#include "test_io_support.hpp"

namespace gen4d::io {
namespace {

using namespace iotest;

TEST(CheckpointFaults, StaleTemporaryIsIgnoredThenRemoved) {
  const std::string dir = scratch_dir("faults_stale_temporary");
  const std::array<long, 3> dims{4, 3, 2};
  const NodeBox box = slab(dims, 2, world_rank(), world_size());
  std::vector<double> x(3 * box.size(), 1.5), v(3 * box.size(), -0.5);
  CheckpointState state;
  state.node_dims = dims;
  state.owned = box;
  state.x = x.data();
  state.v = v.data();
  state.step = 10;
  write_checkpoint(MPI_COMM_WORLD, dir, state, 0);
  // What a run killed while writing step 20 leaves: a hidden, unfinished temporary.
  const std::string stale = dir + "/.checkpoint_00000020.h5.tmp";
  if (world_rank() == 0) std::ofstream(stale) << "half a file";
  MPI_Barrier(MPI_COMM_WORLD);
  EXPECT_EQ(latest_checkpoint(dir), checkpoint_path(dir, 10));
  state.step = 30;
  write_checkpoint(MPI_COMM_WORLD, dir, state, 0);
  EXPECT_FALSE(std::filesystem::exists(stale));
  EXPECT_EQ(latest_checkpoint(dir), checkpoint_path(dir, 30));
  MPI_Barrier(MPI_COMM_WORLD);
}

TEST(WriteFailureCause, NamesAFullDisk) {
  const std::string dir = scratch_dir("faults_cause_space");
  EXPECT_EQ(write_failure_cause(dir + "/a.h5", 1000), "");
  const std::string cause = write_failure_cause(dir + "/a.h5", std::uintmax_t(1) << 62);
  EXPECT_EQ(cause.rfind("no space left on device (", 0), 0u) << cause;
  EXPECT_NE(cause.find(dir), std::string::npos) << cause;
}

TEST(WriteFailureCause, NamesTheFileSizeLimit) {
  const std::string dir = scratch_dir("faults_cause_limit");
  const std::string path = dir + "/big_" + std::to_string(world_rank()) + ".bin";
  std::ofstream(path) << std::string(8192, 'x');
  struct rlimit saved {};
  ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &saved), 0);
  struct rlimit low = saved;
  low.rlim_cur = 8192;
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &low), 0);
  const std::string cause = write_failure_cause(path, 1);
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &saved), 0);
  EXPECT_EQ(cause, "the file size limit (ulimit -f) of 8192 bytes");
}

}  // namespace
}  // namespace gen4d::io
