#include "parallel/Signals.hpp"

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <thread>

#include "parallel/Watchdog.hpp"

namespace gen4d::signals {

namespace {
volatile std::sig_atomic_t g_signal = 0;
extern "C" void on_signal(int sig) {
  g_signal = sig;
}

//! Test hook: GEN4D_TEST_STEP_SECONDS=S makes every step take at least S more seconds of
//! wall time (a sleep, no compute), so that the batch-system tests can make a small deck
//! outlast a one-minute time limit without loading the machine. Unset (the default): 0.
double test_step_seconds() {
  static const double seconds = [] {
    const char* text = std::getenv("GEN4D_TEST_STEP_SECONDS");
    return text != nullptr ? std::max(0.0, std::atof(text)) : 0.0;
  }();
  return seconds;
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
  if (test_step_seconds() > 0)
    std::this_thread::sleep_for(std::chrono::duration<double>(test_step_seconds()));
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
