//! Batch-system signals for long runs: SIGUSR1 asks for a checkpoint, SIGTERM for a checkpoint
//! and a clean stop. The handler only records the signal; runs poll it collectively.
#pragma once

#include <mpi.h>

namespace gen4d::signals {

//! Installs the SIGTERM and SIGUSR1 handlers.
void install();
//! The signal any rank of `comm` received since the last call (0 if none), on every rank.
//! Collective.
int pending(MPI_Comm comm);

}  // namespace gen4d::signals
