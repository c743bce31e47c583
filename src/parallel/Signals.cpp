#include "parallel/Signals.hpp"

#include <csignal>

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
}

int pending(MPI_Comm comm) {
  const int local = static_cast<int>(g_signal);
  int sig = 0;
  MPI_Allreduce(&local, &sig, 1, MPI_INT, MPI_MAX, comm);
  if (sig != 0) g_signal = 0;
  return sig;
}

}  // namespace gen4d::signals
