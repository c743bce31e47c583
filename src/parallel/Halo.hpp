//! Ghost exchange for node fields stored on the rank's ghosted box (x-fastest, dof-interleaved).
#pragma once

#include <petscvec.h>

#include "parallel/Grid.hpp"

namespace gen4d::parallel {

//! Built once per dof count; `gather` refreshes ghost values from their owners,
//! `scatter_add` sums every rank's ghost contributions into the owners (the transposed
//! stencil) and then refreshes the ghosts so the field is consistent everywhere.
class Halo {
 public:
  Halo(const NodeGrid& grid, int dof);
  ~Halo();
  Halo(const Halo&) = delete;
  Halo& operator=(const Halo&) = delete;

  int dof() const { return dof_; }
  //! `field` holds dof values per node of grid.ghosted_nodes(); ghost entries are overwritten.
  void gather(double* field);
  //! Owned entries become the sum of all ranks' entries for that node; ghosts are refreshed.
  void scatter_add(double* field);

 private:
  DM dm_;
  int dof_;
  Vec global_ = nullptr, local_ = nullptr;
};

}  // namespace gen4d::parallel
