//! MPI helpers of the tests: rank and size, a scratch folder per test, a file's bytes.
#pragma once

#include <mpi.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace gen4d::test {

inline int rank_of(MPI_Comm comm) {
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  return rank;
}

inline int size_of(MPI_Comm comm) {
  int size = 1;
  MPI_Comm_size(comm, &size);
  return size;
}

inline int world_rank() {
  return rank_of(MPI_COMM_WORLD);
}

//! An empty scratch folder per test name and rank count under the build tree (collective).
inline std::string scratch_dir(const std::string& name) {
  namespace fs = std::filesystem;
  const std::string d = (fs::path(GEN4D_BINARY_DIR) / "tests" / "scratch" /
                         (name + "_np" + std::to_string(size_of(MPI_COMM_WORLD))))
                            .string();
  if (world_rank() == 0) {
    fs::remove_all(d);
    fs::create_directories(d);
  }
  MPI_Barrier(MPI_COMM_WORLD);
  return d;
}

//! The bytes of a file.
inline std::string bytes_of(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

}  // namespace gen4d::test
