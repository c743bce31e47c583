//! Fault handling of a parallel run: an MPI error handler that names the rank before it aborts
//! the job, and a watchdog thread that aborts a run whose rank makes no progress (a rank hung
//! in a collective that another rank never reaches, or stuck in a step).
#pragma once

#include <mpi.h>

namespace gen4d::watchdog {

//! Replaces MPI_ERRORS_ARE_FATAL on MPI_COMM_WORLD (and the communicators duplicated from it
//! later) with a handler that prints "rank R: MPI error: TEXT" on stderr, then MPI_Abort.
void install_mpi_error_handler();

//! Starts this rank's watchdog thread: when no progress() is recorded for `seconds`, it prints
//! "rank R: watchdog: no progress for S s (PHASE); aborting the job" on stderr and calls
//! MPI_Abort. `seconds` <= 0 starts nothing. Restarts the clock when already running.
void start(double seconds);
//! Stops and joins the thread (no-op when not running).
void stop();
//! Records progress: restarts the clock and names what this rank does next (a string literal).
//! Lock-free; cheap enough for every step.
void progress(const char* phase);
//! Seconds a run waits by default (gen4d run/restart --watchdog).
inline constexpr double kDefaultSeconds = 3600;

//! stop() at the end of a scope.
struct Scope {
  explicit Scope(double seconds) { start(seconds); }
  ~Scope() { stop(); }
  Scope(const Scope&) = delete;
  Scope& operator=(const Scope&) = delete;
};

}  // namespace gen4d::watchdog
