#include "core/ParallelFor.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cstdlib>
#include <thread>

namespace gen4d::exec {

namespace {
int env_int(const char* name) {
  const char* v = std::getenv(name);
  if (!v || !*v) return 0;
  char* end = nullptr;
  const long x = std::strtol(v, &end, 10);
  return (end && *end == '\0' && x > 0 && x < 100000) ? static_cast<int>(x) : 0;
}
}  // namespace

std::string configure_threads() {
#if defined(_OPENMP)
  if (env_int("OMP_NUM_THREADS") > 0)
    return fmt::format("{} host thread(s) per rank (OMP_NUM_THREADS)", omp_get_max_threads());
  int threads = env_int("SLURM_CPUS_PER_TASK");
  const char* why = "SLURM_CPUS_PER_TASK";
  if (threads == 0) {
    const int cores = std::max(1u, std::thread::hardware_concurrency());
    const int local = std::max(1, env_int("OMPI_COMM_WORLD_LOCAL_SIZE"));
    threads = std::max(1, cores / local);
    why = "the node's cores / ranks on the node; set OMP_NUM_THREADS to choose";
  }
  omp_set_num_threads(threads);
  return fmt::format("{} host thread(s) per rank ({})", threads, why);
#else
  return "1 host thread per rank (built without OpenMP)";
#endif
}

}  // namespace gen4d::exec
