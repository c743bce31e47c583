// The checkpoint reader (HDF5): metadata, then the node fields of the whole grid, at one rank.
#include <mpi.h>

#include <cstddef>
#include <cstdint>
#include <vector>

#include "fuzz_common.hpp"
#include "io/Checkpoint.hpp"

extern "C" int LLVMFuzzerInitialize(int* argc, char*** argv) {
  int provided = 0;
  MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = gen4d::fuzz::write_input("checkpoint.h5", data, size);
  gen4d::fuzz::expect_clean_errors([&] {
    const gen4d::io::CheckpointMeta meta = gen4d::io::read_checkpoint_meta(MPI_COMM_WORLD, path);
    // The grid a deck would ask for; larger claims are left out (a run's deck bounds them).
    gen4d::io::NodeBox box;
    box.count = meta.node_dims;
    if (box.empty() || box.size() > (1u << 16)) return;
    std::vector<double> x, v;
    gen4d::io::read_checkpoint_fields(MPI_COMM_WORLD, path, box, x, v);
  });
  return 0;
}
