#include "parallel/Grid.hpp"

#include <algorithm>
#include <string>

#include "core/Error.hpp"
#include "parallel/PetscCheck.hpp"

namespace gen4d::parallel {

NodeGrid::NodeGrid(MPI_Comm comm, const std::array<long, 3>& global_nodes)
    : comm_(comm), global_(global_nodes) {
  MPI_Comm_rank(comm, &rank_);
  MPI_Comm_size(comm, &size_);
  for (int d = 0; d < 3; ++d)
    if (global_[d] < 2)
      throw InputError("grid needs at least 2 nodes per axis, got " + std::to_string(global_[d]));
  check(DMDACreate3d(comm, DM_BOUNDARY_NONE, DM_BOUNDARY_NONE, DM_BOUNDARY_NONE, DMDA_STENCIL_BOX,
                     static_cast<PetscInt>(global_[0]), static_cast<PetscInt>(global_[1]),
                     static_cast<PetscInt>(global_[2]), PETSC_DECIDE, PETSC_DECIDE, PETSC_DECIDE, 3,
                     1, nullptr, nullptr, nullptr, &dm3_),
        "DMDACreate3d");
  check(DMSetUp(dm3_), "DMSetUp");
  // The scalar DM shares the decomposition of the vector one.
  check(DMDACreateCompatibleDMDA(dm3_, 1, &dm1_), "DMDACreateCompatibleDMDA");

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
}

NodeGrid::~NodeGrid() {
  DMDestroy(&dm1_);
  DMDestroy(&dm3_);
}

}  // namespace gen4d::parallel
