//! STREAM triad a = b + s c, the memory-bandwidth baseline every benchmark measures in its own
//! run: arrays far larger than the caches on every rank, best of 5, summed over ranks.
#pragma once

#include <mpi.h>

#include <algorithm>
#include <cstddef>
#include <vector>

namespace gen4d::bench {

inline double stream_triad(std::size_t n) {
  std::vector<double> a(n, 0.0), b(n, 1.0), c(n, 2.0);
  double best = 1e300;
  for (int rep = 0; rep < 5; ++rep) {
    MPI_Barrier(MPI_COMM_WORLD);
    const double t0 = MPI_Wtime();
    const double s = 3.0 + rep;
    for (std::size_t i = 0; i < n; ++i) a[i] = b[i] + s * c[i];
    double t = MPI_Wtime() - t0, tmax = 0;
    MPI_Allreduce(&t, &tmax, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
    best = std::min(best, tmax);
  }
  volatile double sink = a[n / 2];
  (void)sink;
  double bytes = 24.0 * static_cast<double>(n), total = 0;
  MPI_Allreduce(&bytes, &total, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  return total / best;
}

}  // namespace gen4d::bench
