//! Helpers shared by the ElastoGen tests: small decks and gathering a field to rank 0.
#pragma once

#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "core/Config.hpp"
#include "core/Deck.hpp"
#include "elastogen/Simulation.hpp"
#include "mpi_test_util.hpp"

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

//! The largest difference between two gathered position fields, beside the motion scale: the
//! largest velocity component of `v` times `time`.
struct Agreement {
  double diff = 0, motion = 0;
};
inline Agreement agreement(const std::vector<double>& a, const std::vector<double>& b,
                           const std::vector<double>& v, double time) {
  Agreement r;
  for (std::size_t i = 0; i < a.size(); ++i) {
    r.diff = std::max(r.diff, std::fabs(a[i] - b[i]));
    r.motion = std::max(r.motion, std::fabs(v[i]) * time);
  }
  return r;
}

//! `map` applied to the rest position of every ghosted node of the rank.
template <class Map>
std::vector<double> node_field(const elastogen::VoxelSystem& sys, Map map) {
  const auto& G = sys.ghosted();
  std::vector<double> x(3 * G.size());
  for (long k = G.start[2]; k < G.start[2] + G.count[2]; ++k)
    for (long j = G.start[1]; j < G.start[1] + G.count[1]; ++j)
      for (long i = G.start[0]; i < G.start[0] + G.count[0]; ++i) {
        const auto q = map(sys.rest_position(i, j, k));
        for (int d = 0; d < 3; ++d) x[3 * G.index(i, j, k) + d] = q[d];
      }
  return x;
}

}  // namespace gen4d::test
