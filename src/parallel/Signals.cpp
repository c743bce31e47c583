#include "parallel/Signals.hpp"

#include <csignal>

#include "parallel/Watchdog.hpp"

namespace gen4d::signals {

namespace {
volatile std::sig_atomic_t g_signal = 0;
extern "C" void on_signal(int sig) {
  g_signal = sig;
}
}  // namespace

void install() {
  std::signal(SIGTERM, on_signal);
  std::signal(SIGUSR1, on_signal);
  // Past a file size limit (ulimit -f) a write fails with EFBIG and is reported, instead of
  // the process dying of SIGXFSZ halfway through a file.
  std::signal(SIGXFSZ, SIG_IGN);
}

void hold_usr1() {
  std::signal(SIGUSR1, on_signal);
}

int pending(MPI_Comm comm) {
  const int local = static_cast<int>(g_signal);
  int sig = 0;
  // Every step passes here: the watchdog's clock restarts, and a rank that waits here for
  // long waits for a rank that never arrives.
  watchdog::progress("waiting for every rank in the step's signal check, MPI_Allreduce");
  MPI_Allreduce(&local, &sig, 1, MPI_INT, MPI_MAX, comm);
  watchdog::progress("computing a step and writing its output");
  if (sig != 0) g_signal = 0;
  return sig;
}

}  // namespace gen4d::signals
