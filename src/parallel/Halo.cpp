#include "parallel/Halo.hpp"

#include "parallel/PetscCheck.hpp"

namespace gen4d::parallel {

Halo::Halo(const NodeGrid& grid, int dof) : dm_(grid.dm(dof)), dof_(dof) {
  check(DMCreateGlobalVector(dm_, &global_), "DMCreateGlobalVector");
  // The local vector only wraps caller arrays, so it is created without storage.
  PetscInt n = 0, bs = dof;
  Vec probe;
  check(DMGetLocalVector(dm_, &probe), "DMGetLocalVector");
  check(VecGetLocalSize(probe, &n), "VecGetLocalSize");
  check(DMRestoreLocalVector(dm_, &probe), "DMRestoreLocalVector");
  check(VecCreateSeqWithArray(PETSC_COMM_SELF, bs, n, nullptr, &local_), "VecCreateSeqWithArray");
}

Halo::~Halo() {
  VecDestroy(&global_);
  VecDestroy(&local_);
}

void Halo::gather(double* field) {
  // Owned values are already in place: one in-place local-to-local scatter fills the ghosts
  // without staging through a global vector.
  check(VecPlaceArray(local_, field), "VecPlaceArray");
  check(DMLocalToLocalBegin(dm_, local_, INSERT_VALUES, local_), "DMLocalToLocalBegin");
  check(DMLocalToLocalEnd(dm_, local_, INSERT_VALUES, local_), "DMLocalToLocalEnd");
  check(VecResetArray(local_), "VecResetArray");
}

void Halo::scatter_add(double* field) {
  check(VecPlaceArray(local_, field), "VecPlaceArray");
  check(VecZeroEntries(global_), "VecZeroEntries");
  check(DMLocalToGlobal(dm_, local_, ADD_VALUES, global_), "DMLocalToGlobal(ADD)");
  check(DMGlobalToLocalBegin(dm_, global_, INSERT_VALUES, local_), "DMGlobalToLocalBegin");
  check(DMGlobalToLocalEnd(dm_, global_, INSERT_VALUES, local_), "DMGlobalToLocalEnd");
  check(VecResetArray(local_), "VecResetArray");
}

}  // namespace gen4d::parallel
