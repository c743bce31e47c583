//! Helpers shared by the io test suites: slab decompositions, analytic fields, scratch folders.
#pragma once

#include <mpi.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "io/GridBox.hpp"

namespace gen4d::io::iotest {

inline int world_rank() {
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  return rank;
}

inline int world_size() {
  int size = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  return size;
}

//! Part `part` of `parts` slabs of a grid cut along `axis`; empty when the axis is too short.
inline NodeBox slab(const std::array<long, 3>& dims, int axis, int part, int parts) {
  NodeBox box;
  box.count = dims;
  const long begin = dims[axis] * part / parts, end = dims[axis] * (part + 1) / parts;
  box.start[axis] = begin;
  box.count[axis] = end - begin;
  return box;
}

//! Reference node vectors: positions near the rest grid, velocities varying per frame.
inline double position_value(long i, long j, long k, int c, int frame) {
  const double rest[3] = {0.1 * i, 0.1 * j, 0.1 * k};
  return -1.0 + rest[c] + 0.01 * std::sin(0.7 * i + 1.3 * j + 0.4 * k + 0.5 * frame + c);
}
inline double velocity_value(long i, long j, long k, int c, int frame) {
  return std::cos(0.3 * i - 0.9 * j + 1.7 * k + c) * (frame + 1) + 0.125 * c;
}
inline std::uint8_t occupancy_value(long i, long j, long k) {
  return static_cast<std::uint8_t>((i + 2 * j + k) % 3 != 0);
}

//! Values of `field` over `box`, x-fastest, 3 per node.
template <class Field>
std::vector<double> fill_box(const NodeBox& box, int frame, Field field) {
  std::vector<double> values;
  for (long k = box.start[2]; k < box.start[2] + box.count[2]; ++k) {
    for (long j = box.start[1]; j < box.start[1] + box.count[1]; ++j) {
      for (long i = box.start[0]; i < box.start[0] + box.count[0]; ++i) {
        for (int c = 0; c < 3; ++c) values.push_back(field(i, j, k, c, frame));
      }
    }
  }
  if (box.empty()) values.clear();
  return values;
}

inline NodeBox whole(const std::array<long, 3>& dims) {
  return NodeBox{{0, 0, 0}, dims};
}

//! An empty folder for one test at this rank count, shared by all ranks.
inline std::string scratch_dir(const std::string& name) {
  const std::string dir =
      std::string(GEN4D_BINARY_DIR) + "/io_scratch/" + name + "_np" + std::to_string(world_size());
  if (world_rank() == 0) {
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
  }
  MPI_Barrier(MPI_COMM_WORLD);
  return dir;
}

inline std::string file_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

}  // namespace gen4d::io::iotest
