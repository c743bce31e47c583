// Writes the binary seeds of the fuzz corpora that the repository holds no small file for:
// make_seeds DIR writes DIR/fuzz_vdb/sphere.vdb, DIR/fuzz_checkpoint/checkpoint.h5 and
// DIR/fuzz_mesh/tetra_binary.stl (binary STL, after the target's format byte).
#include <mpi.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "io/Checkpoint.hpp"

namespace fs = std::filesystem;

namespace {

void write_vdb(const fs::path& dir) {
  openvdb::initialize();
  auto sphere = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(
      1.0f, openvdb::Vec3f(0, 0, 0), /*voxelSize=*/0.5f, /*halfWidth=*/2.0f);
  sphere->setName("sphere");
  // No zip stream (the fuzzer mutates the tree's bytes); inactive values left out.
  openvdb::io::File file((dir / "sphere.vdb").string());
  file.setCompression(openvdb::io::COMPRESS_ACTIVE_MASK);
  file.write({sphere});
}

void write_checkpoint(const fs::path& dir) {
  gen4d::io::CheckpointState state;
  state.step = 3;
  state.time = 0.25;
  state.frame_index = 1;
  state.next_frame_time = 0.5;
  state.deck_text = "[simulation]\nend = 1\n";
  state.extras = {{"energy", -1.5}};
  state.node_dims = {2, 2, 1};
  state.owned.count = state.node_dims;
  std::vector<double> x(3 * state.owned.size(), 0.5), v(3 * state.owned.size(), -0.25);
  state.x = x.data();
  state.v = v.data();
  const std::string path = gen4d::io::write_checkpoint(MPI_COMM_WORLD, dir.string(), state, 0);
  fs::rename(path, dir / "checkpoint.h5");
}

void write_binary_stl(const fs::path& dir) {
  const float p[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  const int tri[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  std::string bytes = "1";  // the target's format byte: STL
  bytes += std::string(80, ' ');
  const std::uint32_t count = 4;
  bytes.append(reinterpret_cast<const char*>(&count), 4);
  for (const auto& t : tri) {
    const float normal[3] = {0, 0, 0};
    bytes.append(reinterpret_cast<const char*>(normal), sizeof normal);
    for (int k : t) bytes.append(reinterpret_cast<const char*>(p[k]), sizeof p[k]);
    bytes.append(2, '\0');
  }
  std::ofstream((dir / "tetra_binary.stl").string(), std::ios::binary) << bytes;
}

}  // namespace

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_seeds CORPUS_DIR\n");
    MPI_Abort(MPI_COMM_WORLD, 2);
  }
  const fs::path root = argv[1];
  for (const char* target : {"fuzz_vdb", "fuzz_checkpoint", "fuzz_mesh"})
    fs::create_directories(root / target);
  write_vdb(root / "fuzz_vdb");
  write_checkpoint(root / "fuzz_checkpoint");
  write_binary_stl(root / "fuzz_mesh");
  MPI_Finalize();
  return 0;
}
