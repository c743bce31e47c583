// gen4d — physically based 4D content on clusters.
//
// Sample runs:
//   mpirun -np 2 gen4d run                          (embedded default scene)
//   mpirun -np 2 gen4d run inputs/beam.toml --out beam --set material.youngs_modulus=2e5
//   mpirun -np 4 gen4d restart beam/checkpoint_000200.h5
//   gen4d preview beam/frames.h5 --out beam/png --frames 0,10,-1
//   gen4d info
//
// Exit codes: 0 success, 2 bad input (deck, files, command line), 1 runtime failure or a
// run stopped by SIGTERM (a checkpoint is written first).
#include <CLI/CLI.hpp>
#include <mpi.h>
#include <petscsys.h>

#include <cstdio>
#include <exception>
#include <string>

#include "cli/Commands.hpp"
#include "core/Error.hpp"
#include "core/Log.hpp"
#include "core/ParallelFor.hpp"
#include "parallel/Signals.hpp"
#include "parallel/Watchdog.hpp"
#ifdef GEN4D_WITH_TORCH
#include "neural_train/Install.hpp"
#endif

namespace {
// One line for the user, the same on every rank, printed once.
int fail(int code, const std::string& msg, int rank) {
  if (rank == 0) gen4d::log::error_str(msg);
  return code;
}
}  // namespace

int main(int argc, char** argv) {
  // A batch system's early SIGUSR1 ("checkpoint soon") must not kill the process.
  gen4d::signals::hold_usr1();
  int provided = 0;
  MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  gen4d::log::set_rank(rank);
  // An MPI error names its rank before the job is aborted.
  gen4d::watchdog::install_mpi_error_handler();
  gen4d::exec::configure_threads();  // OMP_NUM_THREADS, else the node's cores per rank
  // gen4d handles SIGTERM/SIGUSR1 itself (checkpoint, then stop); PETSc must not trap them.
  PetscOptionsSetValue(nullptr, "-no_signal_handler", nullptr);
  PetscOptionsSetValue(nullptr, "-options_left", "0");
  PetscInitializeNoArguments();
#ifdef GEN4D_WITH_TORCH
  gen4d::neural_train::install_weight_generator();  // target "neural" without a weight file
#endif

  int code = 0;
  try {
    code = gen4d::cli::dispatch(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version are "errors" to CLI11 with exit code 0.
    if (rank == 0) {
      if (e.get_exit_code() == 0)
        std::fputs(e.what(), stdout);
      else
        gen4d::log::error_str(std::string("command line: ") + e.what() + " (see gen4d --help)");
    }
    code = e.get_exit_code() == 0 ? 0 : 2;
  } catch (const gen4d::InputError& e) {
    code = fail(2, e.what(), rank);
  } catch (const gen4d::RuntimeError& e) {
    code = fail(1, e.what(), rank);
  } catch (const std::exception& e) {
    code = fail(1, std::string("internal error: ") + e.what(), rank);
  }
  // Ranks may fail alone (a file only one of them read): agree on the worst code.
  int global = code;
  MPI_Allreduce(&code, &global, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  PetscFinalize();
  MPI_Finalize();
  return global;
}
