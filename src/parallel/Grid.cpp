#include "parallel/Grid.hpp"

#include <algorithm>
#include <string>

#include "core/Error.hpp"
#include "parallel/PetscCheck.hpp"

namespace gen4d::parallel {

NodeGrid::NodeGrid(MPI_Comm comm, const std::array<long, 3>& global_nodes)
    : comm_(comm), global_(global_nodes) {
  init(nullptr);
}

NodeGrid::NodeGrid(MPI_Comm comm, const std::array<long, 3>& global_nodes,
                   const std::array<std::vector<long>, 3>& ownership)
    : comm_(comm), global_(global_nodes) {
  init(&ownership);
}

std::array<int, 3> NodeGrid::process_grid(MPI_Comm comm, const std::array<long, 3>& nodes) {
  DM dm = nullptr;
  check(DMDACreate3d(comm, DM_BOUNDARY_NONE, DM_BOUNDARY_NONE, DM_BOUNDARY_NONE, DMDA_STENCIL_BOX,
                     static_cast<PetscInt>(nodes[0]), static_cast<PetscInt>(nodes[1]),
                     static_cast<PetscInt>(nodes[2]), PETSC_DECIDE, PETSC_DECIDE, PETSC_DECIDE, 1,
                     1, nullptr, nullptr, nullptr, &dm),
        "DMDACreate3d");
  check(DMSetUp(dm), "DMSetUp");
  PetscInt m = 1, n = 1, p = 1;
  check(DMDAGetInfo(dm, nullptr, nullptr, nullptr, nullptr, &m, &n, &p, nullptr, nullptr, nullptr,
                    nullptr, nullptr, nullptr),
        "DMDAGetInfo");
  DMDestroy(&dm);
  return {static_cast<int>(m), static_cast<int>(n), static_cast<int>(p)};
}

int NodeGrid::owner_of(long i, long j, long k) const {
  const long idx[3] = {i, j, k};
  int coord[3];
  for (int a = 0; a < 3; ++a) {
    const auto& s = starts_[a];
    const auto it = std::upper_bound(s.begin(), s.end() - 1, idx[a]);
    coord[a] = std::max(0, static_cast<int>(it - s.begin()) - 1);
  }
  const int m = static_cast<int>(starts_[0].size()) - 1;
  const int n = static_cast<int>(starts_[1].size()) - 1;
  return (coord[2] * n + coord[1]) * m + coord[0];
}

void NodeGrid::init(const std::array<std::vector<long>, 3>* ownership) {
  MPI_Comm_rank(comm_, &rank_);
  MPI_Comm_size(comm_, &size_);
  for (int d = 0; d < 3; ++d)
    if (global_[d] < 2)
      throw InputError("grid needs at least 2 nodes per axis, got " + std::to_string(global_[d]));
  std::array<std::vector<PetscInt>, 3> lx;
  PetscInt procs[3] = {PETSC_DECIDE, PETSC_DECIDE, PETSC_DECIDE};
  if (ownership) {
    for (int a = 0; a < 3; ++a) {
      lx[a].assign((*ownership)[a].begin(), (*ownership)[a].end());
      procs[a] = static_cast<PetscInt>(lx[a].size());
    }
  }
  check(DMDACreate3d(comm_, DM_BOUNDARY_NONE, DM_BOUNDARY_NONE, DM_BOUNDARY_NONE, DMDA_STENCIL_BOX,
                     static_cast<PetscInt>(global_[0]), static_cast<PetscInt>(global_[1]),
                     static_cast<PetscInt>(global_[2]), procs[0], procs[1], procs[2], 3, 1,
                     ownership ? lx[0].data() : nullptr, ownership ? lx[1].data() : nullptr,
                     ownership ? lx[2].data() : nullptr, &dm3_),
        "DMDACreate3d");
  check(DMSetUp(dm3_), "DMSetUp");
  // The scalar DM shares the decomposition of the vector one.
  check(DMDACreateCompatibleDMDA(dm3_, 1, &dm1_), "DMDACreateCompatibleDMDA");
  check(DMDACreateCompatibleDMDA(dm3_, 4, &dm4_), "DMDACreateCompatibleDMDA");

  PetscInt xs, ys, zs, xm, ym, zm;
  check(DMDAGetCorners(dm3_, &xs, &ys, &zs, &xm, &ym, &zm), "DMDAGetCorners");
  owned_ = Box{{xs, ys, zs}, {xm, ym, zm}};
  check(DMDAGetGhostCorners(dm3_, &xs, &ys, &zs, &xm, &ym, &zm), "DMDAGetGhostCorners");
  ghosted_ = Box{{xs, ys, zs}, {xm, ym, zm}};
  for (int d = 0; d < 3; ++d) {
    const long lo = std::max(0L, owned_.start[d] - 1);
    const long hi = std::min(global_[d] - 1, owned_.start[d] + owned_.count[d]);
    cells_.start[d] = lo;
    cells_.count[d] = std::max(0L, hi - lo);
    const long olo = owned_.start[d];
    const long ohi = std::min(global_[d] - 1, owned_.start[d] + owned_.count[d]);
    owned_cells_.start[d] = olo;
    owned_cells_.count[d] = std::max(0L, ohi - olo);
  }
  const PetscInt* ranges[3] = {nullptr, nullptr, nullptr};
  check(DMDAGetOwnershipRanges(dm3_, &ranges[0], &ranges[1], &ranges[2]), "DMDAGetOwnershipRanges");
  PetscInt m = 1, n = 1, p = 1;
  check(DMDAGetInfo(dm3_, nullptr, nullptr, nullptr, nullptr, &m, &n, &p, nullptr, nullptr, nullptr,
                    nullptr, nullptr, nullptr),
        "DMDAGetInfo");
  const PetscInt counts[3] = {m, n, p};
  for (int a = 0; a < 3; ++a) {
    starts_[a].assign(1, 0);
    for (PetscInt q = 0; q < counts[a]; ++q) starts_[a].push_back(starts_[a].back() + ranges[a][q]);
  }
}

NodeGrid::~NodeGrid() {
  DMDestroy(&dm1_);
  DMDestroy(&dm4_);
  DMDestroy(&dm3_);
}

}  // namespace gen4d::parallel
