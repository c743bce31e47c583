//! A small voxel scene for ElastoGen's kernel tests: a notched block with two materials and a
//! held face, so the sweep meets interior runs, general rows (empty neighbours, the denser
//! slot) and held nodes; more than 2048 nodes so the host loops really run threaded.
#pragma once

#include <mpi.h>

#include <memory>
#include <random>
#include <vector>

#include "elastogen/VoxelSystem.hpp"

namespace gen4d::test {

struct KernelScene {
  std::unique_ptr<parallel::NodeGrid> grid;
  std::unique_ptr<elastogen::VoxelSystem> sys;
  double k = 0, inv_dt2 = 1e4;
  std::vector<double> diag, r, d;  //!< diagonal, right-hand side, iterate (ghosted arrays)
};

inline KernelScene kernel_scene() {
  KernelScene s;
  s.grid = std::make_unique<parallel::NodeGrid>(MPI_COMM_SELF, std::array<long, 3>{24, 12, 10});
  const parallel::Box& C = s.grid->adjacent_cells();
  std::vector<std::uint8_t> occ(C.size(), 0);
  for (long ck = C.start[2]; ck < C.start[2] + C.count[2]; ++ck)
    for (long cj = C.start[1]; cj < C.start[1] + C.count[1]; ++cj)
      for (long ci = C.start[0]; ci < C.start[0] + C.count[0]; ++ci) {
        if (ci < 0 || cj < 0 || ck < 0 || ci > 22 || cj > 10 || ck > 8) continue;
        if (ci > 15 && ck > 5) continue;  // the notch: empty voxels inside the box
        occ[C.index(ci, cj, ck)] = (ci > 8 && ci < 12 && cj > 4) ? 2 : 1;
      }
  const std::vector<BoxRegion> held{{{-1.0, -1.0, -1.0}, {0.01, 1.0, 1.0}}};
  s.sys = std::make_unique<elastogen::VoxelSystem>(*s.grid, Vec3d{0, 0, 0}, 0.05, occ,
                                                   std::vector<double>{1000.0, 2500.0}, held);
  s.k = 3e6;
  s.sys->diagonal(s.k, s.inv_dt2, s.diag);
  const std::size_t n = 3 * s.sys->ghosted().size();
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  s.r.assign(n, 0.0);
  s.d.assign(n, 0.0);
  for (std::size_t q = 0; q < n; ++q) {
    s.d[q] = 1e-3 * u(rng);
    s.r[q] = s.sys->free_mask()[q / 3] ? u(rng) : 0.0;
  }
  return s;
}

}  // namespace gen4d::test
