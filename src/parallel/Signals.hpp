//! Batch-system signals for long runs: SIGUSR1 asks for a checkpoint, SIGTERM for a checkpoint
//! and a clean stop. The handler only records the signal; runs poll it collectively.
#pragma once

#include <mpi.h>

namespace gen4d::signals {

//! Installs the SIGTERM and SIGUSR1 handlers, and ignores SIGXFSZ (a write past ulimit -f
//! then fails with EFBIG and is reported like a full disk).
void install();
//! Records SIGUSR1 from the program's start: a batch system's early "checkpoint soon" must not
//! kill the process (its default action). A run acts on it at its first step; other commands
//! never look.
void hold_usr1();
//! The signal any rank of `comm` received since the last call (0 if none), on every rank.
//! Collective; also the watchdog's progress mark (parallel/Watchdog.hpp). With the test hook
//! GEN4D_TEST_STEP_SECONDS=S set, each call first sleeps S seconds (slow steps, no load).
int pending(MPI_Comm comm);

}  // namespace gen4d::signals
