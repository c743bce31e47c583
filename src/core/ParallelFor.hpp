//! One loop launcher for the pointwise kernels, on the CPU and on a GPU (after AMReX's
//! ParallelFor and Kokkos' parallel_for).
//
// A kernel is a callable `GEN4D_HD void operator()(long i) const` (a functor in a header, or a
// lambda) that touches only what it captures: raw pointers and sizes, never MPI or containers.
// The same source then runs
//   - on the host through `exec::parallel_for` (OpenMP, static schedule, OMP_NUM_THREADS
//     honoured; serial in a build without OpenMP), and
//   - on a GPU through `exec::device_for` (one CUDA thread per index), compiled only by nvcc:
//     the `.cu` files of each module instantiate their kernels and nothing else.
// Reductions use `parallel_reduce_max` / `parallel_reduce_sum_long` (host); kernels needing
// order-independent sums accumulate integers (see mpm/Solver.hpp).
#pragma once

#include <cstddef>
#include <string>

#include "materials/Hd.hpp"

#if defined(_OPENMP)
#include <omp.h>
#endif

namespace gen4d::exec {

//! Threads the host loops use (omp_get_max_threads; 1 without OpenMP).
inline int host_threads() {
#if defined(_OPENMP)
  return omp_get_max_threads();
#else
  return 1;
#endif
}

//! Loops shorter than this run serially: a parallel region costs a few microseconds.
inline constexpr long kSerialBelow = 2048;

//! f(begin, end) on contiguous blocks of [0, n), one block per thread: for loops that keep a
//! per-block accumulator or scratch.
template <class F>
void parallel_blocks(long n, const F& f) {
#if defined(_OPENMP)
  if (n >= kSerialBelow && omp_get_max_threads() > 1) {
#pragma omp parallel
    {
      const long t = omp_get_thread_num(), T = omp_get_num_threads();
      f(n * t / T, n * (t + 1) / T);
    }
    return;
  }
#endif
  f(0L, n);
}

//! f(i) for i in [0, n) on the host's threads, static contiguous chunks (thread t gets the t-th
//! block, so per-thread work is as local as the data).
template <class F>
void parallel_for(long n, const F& f) {
  parallel_blocks(n, [&f](long begin, long end) {
    for (long i = begin; i < end; ++i) f(i);
  });
}

//! f(i) for i in [0, n), items handed out one at a time to the next free thread: for items of
//! very uneven cost (image tiles).
template <class F>
void parallel_for_dynamic(long n, const F& f) {
#if defined(_OPENMP)
  if (n > 1 && omp_get_max_threads() > 1) {
#pragma omp parallel for schedule(dynamic, 1)
    for (long i = 0; i < n; ++i) f(i);
    return;
  }
#endif
  for (long i = 0; i < n; ++i) f(i);
}

//! max over i of f(i) (f returns double; the result does not depend on the thread count).
template <class F>
double parallel_reduce_max(long n, double init, const F& f) {
  double out = init;
#if defined(_OPENMP)
  if (n >= kSerialBelow && omp_get_max_threads() > 1) {
#pragma omp parallel for schedule(static) reduction(max : out)
    for (long i = 0; i < n; ++i) {
      const double v = f(i);
      out = v > out ? v : out;
    }
    return out;
  }
#endif
  for (long i = 0; i < n; ++i) {
    const double v = f(i);
    out = v > out ? v : out;
  }
  return out;
}

//! Sum over i of the integer f(i) (exact, so independent of the thread count).
template <class F>
long long parallel_reduce_sum(long n, const F& f) {
  long long out = 0;
#if defined(_OPENMP)
  if (n >= kSerialBelow && omp_get_max_threads() > 1) {
#pragma omp parallel for schedule(static) reduction(+ : out)
    for (long i = 0; i < n; ++i) out += f(i);
    return out;
  }
#endif
  for (long i = 0; i < n; ++i) out += f(i);
  return out;
}

#if defined(__CUDACC__)
namespace detail {
template <class F>
__global__ void for_kernel(long n, F f) {
  const long i = static_cast<long>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i < n) f(i);
}
}  // namespace detail

//! f(i) for i in [0, n) on the current CUDA device (asynchronous on `stream`).
template <class F>
void device_for(long n, const F& f, cudaStream_t stream = nullptr) {
  if (n <= 0) return;
  constexpr int kBlock = 256;
  const long blocks = (n + kBlock - 1) / kBlock;
  detail::for_kernel<<<static_cast<unsigned>(blocks), kBlock, 0, stream>>>(n, f);
}
#endif

//! Sets the host threads per rank when OMP_NUM_THREADS is unset: the node's cores shared
//! by the ranks on the node (OpenMPI's OMPI_COMM_WORLD_LOCAL_SIZE, Slurm's
//! SLURM_CPUS_PER_TASK), at least 1, so that ranks x threads never oversubscribes the node.
//! Returns a line for the log ("2 threads per rank (OMP_NUM_THREADS)").
std::string configure_threads();

}  // namespace gen4d::exec
