#include "parallel/Watchdog.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <thread>

namespace gen4d::watchdog {
namespace {

using Clock = std::chrono::steady_clock;

std::atomic<long long> g_last{0};  // Clock ticks of the last progress()
std::atomic<const char*> g_phase{"starting the run"};
std::mutex g_mutex;
std::condition_variable g_wake;
bool g_stop = false;
std::thread g_thread;

long long now_ticks() {
  return Clock::now().time_since_epoch().count();
}

int world_rank() {
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  return rank;
}

extern "C" void on_mpi_error(MPI_Comm* /*comm*/, int* code, ...) {
  char text[MPI_MAX_ERROR_STRING] = "";
  int length = 0;
  MPI_Error_string(*code, text, &length);
  std::fprintf(stderr, "[rank %d] error: MPI: %s; aborting the job\n", world_rank(), text);
  std::fflush(stderr);
  MPI_Abort(MPI_COMM_WORLD, 1);
  std::_Exit(1);
}

void watch(double seconds, int rank) {
  const auto limit =
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
  std::unique_lock<std::mutex> lock(g_mutex);
  while (!g_stop) {
    const Clock::time_point last{Clock::duration(g_last.load())};
    const Clock::time_point deadline = last + limit;
    if (Clock::now() >= deadline) {
      std::fprintf(stderr,
                   "[rank %d] error: watchdog: rank %d made no progress for %g s (%s); a rank "
                   "is hung or dead; aborting the job\n",
                   rank, rank, seconds, g_phase.load());
      std::fflush(stderr);
      // MPI_Abort from this thread: the main thread is blocked, and mpirun must end every rank.
      MPI_Abort(MPI_COMM_WORLD, 1);
      std::_Exit(1);
    }
    g_wake.wait_until(lock, std::min(deadline, Clock::now() + std::chrono::seconds(1)));
  }
}

}  // namespace

void install_mpi_error_handler() {
  MPI_Errhandler handler;
  MPI_Comm_create_errhandler(on_mpi_error, &handler);
  MPI_Comm_set_errhandler(MPI_COMM_WORLD, handler);
  MPI_Errhandler_free(&handler);
}

void progress(const char* phase) {
  g_phase.store(phase);
  g_last.store(now_ticks());
}

void start(double seconds) {
  stop();
  if (!(seconds > 0)) return;
  progress("starting the run");
  {
    std::lock_guard<std::mutex> lock(g_mutex);
    g_stop = false;
  }
  g_thread = std::thread(watch, seconds, world_rank());
}

void stop() {
  if (!g_thread.joinable()) return;
  {
    std::lock_guard<std::mutex> lock(g_mutex);
    g_stop = true;
  }
  g_wake.notify_all();
  g_thread.join();
}

}  // namespace gen4d::watchdog
