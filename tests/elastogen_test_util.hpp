//! Helpers shared by the ElastoGen tests: small decks and gathering a field to rank 0.
#pragma once

#include <mpi.h>

#include <filesystem>
#include <string>
#include <vector>

#include "core/Config.hpp"
#include "core/Deck.hpp"
#include "elastogen/Simulation.hpp"

namespace gen4d::test {

//! Positions of all nodes in global x-fastest order, on rank 0 (empty elsewhere).
inline std::vector<double> gather_positions(elastogen::Simulation& sim, bool velocities = false) {
  const auto& g = sim.grid();
  const auto& O = g.owned_nodes();
  const auto local = velocities ? sim.owned_velocities() : sim.owned_positions();
  long box[6] = {O.start[0], O.start[1], O.start[2], O.count[0], O.count[1], O.count[2]};
  std::vector<long> boxes(6 * g.size());
  MPI_Gather(box, 6, MPI_LONG, boxes.data(), 6, MPI_LONG, 0, g.comm());
  const int n = static_cast<int>(local.size());
  std::vector<int> counts(g.size()), displs(g.size());
  MPI_Gather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, g.comm());
  int total = 0;
  for (int r = 0; r < g.size(); ++r) {
    displs[r] = total;
    total += counts[r];
  }
  std::vector<double> all(g.rank() == 0 ? total : 0);
  MPI_Gatherv(local.data(), n, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE, 0,
              g.comm());
  if (g.rank() != 0) return {};
  const auto& dims = g.global_nodes();
  std::vector<double> out(3 * dims[0] * dims[1] * dims[2]);
  for (int r = 0; r < g.size(); ++r) {
    const long* b = &boxes[6 * r];
    std::size_t p = displs[r] / 3;
    for (long k = b[2]; k < b[2] + b[5]; ++k)
      for (long j = b[1]; j < b[1] + b[4]; ++j)
        for (long i = b[0]; i < b[0] + b[3]; ++i, ++p)
          for (int d = 0; d < 3; ++d)
            out[3 * ((k * dims[1] + j) * dims[0] + i) + d] = all[3 * p + d];
  }
  return out;
}

inline int world_rank() {
  int r = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &r);
  return r;
}

//! An empty scratch folder per test name and rank count under the build tree (collective).
inline std::string scratch_dir(const std::string& name) {
  namespace fs = std::filesystem;
  int size = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  const std::string d =
      (fs::path(GEN4D_BINARY_DIR) / "tests" / "scratch" / (name + "_np" + std::to_string(size)))
          .string();
  if (world_rank() == 0) {
    fs::remove_all(d);
    fs::create_directories(d);
  }
  MPI_Barrier(MPI_COMM_WORLD);
  return d;
}

}  // namespace gen4d::test
