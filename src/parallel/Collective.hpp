//! Collective helpers around work that only one rank does.
#pragma once

#include <mpi.h>

#include <functional>
#include <string>

namespace gen4d::parallel {

//! Runs `work` on rank 0 only; if it throws, every rank throws a RuntimeError (rank 0 with the
//! original message, the others with `elsewhere`). Collective.
void on_rank0(MPI_Comm comm, const std::string& elsewhere, const std::function<void()>& work);

}  // namespace gen4d::parallel
