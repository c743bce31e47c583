//! Shared by the validation and benchmark drivers: MPI/PETSc start-up with the CLI parse and
//! the exit-code convention (0 pass, 1 target missed or failure, 2 bad input), and probes
//! of a beam's free end.
#pragma once

#include <mpi.h>
#include <petscsys.h>

#include <CLI/CLI.hpp>
#include <exception>
#include <algorithm>
#include <functional>
#include <initializer_list>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "core/Error.hpp"
#include "core/Log.hpp"
#include "core/ParallelFor.hpp"
#include "elastogen/Simulation.hpp"
#ifdef GEN4D_WITH_TORCH
#include "neural_train/Install.hpp"
#endif

namespace gen4d::driver {

//! Initialises MPI and PETSc, lets `setup` add options to the app, parses, runs `body` and
//! maps exceptions to exit codes. Returns the process exit code.
inline int main_with(int argc, char** argv, const char* description,
                     const std::function<void(CLI::App&)>& setup,
                     const std::function<int()>& body) {
  MPI_Init(&argc, &argv);
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  log::set_rank(rank);
  exec::configure_threads();  // OMP_NUM_THREADS, else the node's cores per rank
  PetscOptionsSetValue(nullptr, "-no_signal_handler", nullptr);
  PetscInitializeNoArguments();
#ifdef GEN4D_WITH_TORCH
  neural_train::install_weight_generator();  // decks with target "neural" and no weight file
#endif
  CLI::App app{description};
  setup(app);
  int code = 0;
  try {
    app.parse(argc, argv);
    code = body();
  } catch (const CLI::ParseError& e) {
    code = app.exit(e);
  } catch (const InputError& e) {
    if (rank == 0) log::error_str(e.what());
    code = 2;
  } catch (const std::exception& e) {
    if (rank == 0) log::error_str(e.what());
    code = 1;
  }
  PetscFinalize();
  MPI_Finalize();
  return code;
}

//! The comma-separated numbers that `option` (e.g. "--ratios") was given; an entry that is
//! not a number is an InputError naming it.
inline std::vector<double> number_list(const std::string& text, const std::string& option) {
  std::vector<double> v;
  std::stringstream ss(text);
  for (std::string s; std::getline(ss, s, ',');) {
    try {
      v.push_back(std::stod(s));
    } catch (const std::exception&) {
      throw InputError(option + ": '" + s + "' is not a number");
    }
  }
  return v;
}

//! Lowers each value to its cap (what a driver's --quick does to its sizes).
inline void cap(std::initializer_list<std::pair<int*, int>> caps) {
  for (const auto& [value, most] : caps) *value = std::min(*value, most);
}

//! Where a driver's body runs: on every rank, or on rank 0 alone (serial work; every rank
//! returns rank 0's exit code).
enum Ranks { AllRanks, RankZero };

//! main_with for a driver whose options are a struct `O` declaring them in
//! `void add(CLI::App&)`: parses into a default `O` and returns `run(o)`.
template <class O>
int main_with_options(int argc, char** argv, const char* description, int (*run)(const O&),
                      Ranks ranks = AllRanks) {
  O o;
  return main_with(
      argc, argv, description, [&](CLI::App& app) { o.add(app); },
      [&] {
        if (ranks == AllRanks) return run(o);
        int rank = 0;
        MPI_Comm_rank(MPI_COMM_WORLD, &rank);
        int code = rank == 0 ? run(o) : 0;
        MPI_Bcast(&code, 1, MPI_INT, 0, MPI_COMM_WORLD);
        return code;
      });
}

//! Mean position component `d` of the object's nodes on the grid plane i = last (the free
//! end of a beam along x with padding 0), summed over ranks.
inline double end_face_mean(elastogen::Simulation& sim, int d) {
  const auto& g = sim.grid();
  const auto& O = g.owned_nodes();
  const auto& G = g.ghosted_nodes();
  const long i = g.global_nodes()[0] - 1;
  double local[2] = {0, 0}, global[2];
  if (i >= O.start[0] && i < O.start[0] + O.count[0])
    for (long k = O.start[2]; k < O.start[2] + O.count[2]; ++k)
      for (long j = O.start[1]; j < O.start[1] + O.count[1]; ++j)
        if (sim.system().mass()[G.index(i, j, k)] > 0) {
          local[0] += sim.dynamics().x()[3 * G.index(i, j, k) + d];
          local[1] += 1;
        }
  MPI_Allreduce(local, global, 2, MPI_DOUBLE, MPI_SUM, g.comm());
  return global[0] / global[1];
}

}  // namespace gen4d::driver
