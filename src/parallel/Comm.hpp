//! The communicator and the small collectives the solvers use, so that no module outside
//! `parallel` and `io` talks MPI itself. Every function is collective on `comm`.
#pragma once

#include <mpi.h>

#include <cstdint>
#include <cstring>
#include <string>
#include <type_traits>
#include <vector>

namespace gen4d::parallel {

int rank(MPI_Comm comm);
int size(MPI_Comm comm);
//! Seconds on MPI's wall clock (not collective).
double wall_seconds();

//! Element-wise over every rank, in place: the largest, the smallest, the sum.
void max_in_place(MPI_Comm comm, double* values, int n);
void min_in_place(MPI_Comm comm, double* values, int n);
void sum_in_place(MPI_Comm comm, long long* values, int n);
//! Floating-point sums depend on MPI's order of the ranks: for timings and counts, never for
//! results that must agree bit for bit across rank counts (parallel::Reducer sums exactly).
void sum_in_place(MPI_Comm comm, double* values, int n);
//! Waits until every rank has called it.
void barrier(MPI_Comm comm);
inline double max_of(MPI_Comm comm, double local) {
  max_in_place(comm, &local, 1);
  return local;
}
inline double min_of(MPI_Comm comm, double local) {
  min_in_place(comm, &local, 1);
  return local;
}
long long max_of(MPI_Comm comm, long long local);
long long min_of(MPI_Comm comm, long long local);
inline long long sum_of(MPI_Comm comm, long long local) {
  sum_in_place(comm, &local, 1);
  return local;
}

//! Element-wise largest of every rank's n floats, on `root` (out may be null elsewhere).
void max_to_root(MPI_Comm comm, const float* local, float* out, int n, int root = 0);

//! The sum of `local` over the ranks below this one (0 on rank 0).
std::int64_t exclusive_prefix_sum(MPI_Comm comm, std::int64_t local);

//! `root`'s text on every rank.
std::string broadcast(MPI_Comm comm, std::string text, int root = 0);

//! Raw bytes of the collectives below (trivially copyable values travel as bytes).
void broadcast_bytes(MPI_Comm comm, void* data, std::size_t bytes, int root);
std::vector<unsigned char> gather_bytes(MPI_Comm comm, const void* data, std::size_t bytes,
                                        int root, std::vector<std::size_t>* counts);
std::vector<unsigned char> all_gather_bytes(MPI_Comm comm, const void* data, std::size_t bytes);

//! `root`'s n values on every rank.
template <class T>
void broadcast(MPI_Comm comm, T* values, std::size_t n, int root = 0) {
  static_assert(std::is_trivially_copyable_v<T>);
  broadcast_bytes(comm, values, n * sizeof(T), root);
}

//! Every rank's values, in rank order, on `root` (empty elsewhere); `counts` (when given)
//! receives the number of values from each rank, on `root`.
template <class T>
std::vector<T> gather(MPI_Comm comm, const std::vector<T>& local, int root = 0,
                      std::vector<std::size_t>* counts = nullptr) {
  static_assert(std::is_trivially_copyable_v<T>);
  const std::vector<unsigned char> bytes =
      gather_bytes(comm, local.data(), local.size() * sizeof(T), root, counts);
  if (counts)
    for (auto& c : *counts) c /= sizeof(T);
  std::vector<T> out(bytes.size() / sizeof(T));
  if (!bytes.empty()) std::memcpy(out.data(), bytes.data(), bytes.size());
  return out;
}

//! Every rank's values, in rank order, on every rank.
template <class T>
std::vector<T> all_gather(MPI_Comm comm, const std::vector<T>& local) {
  static_assert(std::is_trivially_copyable_v<T>);
  const std::vector<unsigned char> bytes =
      all_gather_bytes(comm, local.data(), local.size() * sizeof(T));
  std::vector<T> out(bytes.size() / sizeof(T));
  if (!bytes.empty()) std::memcpy(out.data(), bytes.data(), bytes.size());
  return out;
}

}  // namespace gen4d::parallel
