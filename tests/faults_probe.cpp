// The fault handlers of src/parallel/Watchdog.hpp in a 2-rank job, for tests/cli_faults_probe.sh:
//   mpi-error       rank 1 makes an invalid MPI call (a send to a rank that does not exist)
//                   while rank 0 waits in a barrier: the handler names rank 1 and aborts.
//   hang            rank 1 never reaches the barrier rank 0 waits in (and has no watchdog, as
//                   a stopped process): rank 0's 2 s watchdog names rank 0 and aborts.
//   stuck           rank 1 never leaves its step, with a 2 s watchdog on rank 1 alone: it
//                   names rank 1 and aborts.
//   progress        both ranks record progress every 0.2 s for 3 s under a 1 s watchdog, then
//                   stop it: no abort, exit 0.
#include <mpi.h>

#include <chrono>
#include <cstdio>
#include <string>
#include <thread>

#include "parallel/Watchdog.hpp"

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  gen4d::watchdog::install_mpi_error_handler();
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  const std::string mode = argc > 1 ? argv[1] : "";
  if (mode == "mpi-error") {
    if (rank == 1) {
      int value = 0;
      MPI_Send(&value, 1, MPI_INT, size + 5, 0, MPI_COMM_WORLD);
    }
    MPI_Barrier(MPI_COMM_WORLD);
  } else if (mode == "hang" || mode == "stuck") {
    // hang: rank 1 is stopped (its watchdog cannot run), rank 0 waits for it in the barrier.
    // stuck: rank 1 runs but never leaves its step; only its own watchdog runs.
    if ((mode == "hang") == (rank == 0)) gen4d::watchdog::start(2);
    gen4d::watchdog::progress(rank == 0 ? "waiting in the probe's barrier"
                                        : "in the probe's endless step");
    if (rank == 1) std::this_thread::sleep_for(std::chrono::seconds(60));
    MPI_Barrier(MPI_COMM_WORLD);
  } else if (mode == "progress") {
    gen4d::watchdog::start(1);
    for (int i = 0; i < 15; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
      gen4d::watchdog::progress("sleeping");
    }
    gen4d::watchdog::stop();
    MPI_Barrier(MPI_COMM_WORLD);
  } else {
    if (rank == 0) std::fprintf(stderr, "usage: faults_probe mpi-error|hang|stuck|progress\n");
    MPI_Finalize();
    return 2;
  }
  if (rank == 0) std::printf("probe %s: finished\n", mode.c_str());
  MPI_Finalize();
  return 0;
}
