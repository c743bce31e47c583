#include "parallel/Comm.hpp"

#include <climits>
#include <stdexcept>

namespace gen4d::parallel {

namespace {

int as_int(std::size_t n, const char* what) {
  if (n > static_cast<std::size_t>(INT_MAX))
    throw std::length_error(std::string(what) + ": more than 2^31 bytes in one MPI call");
  return static_cast<int>(n);
}

//! Counts and displacements (bytes) of every rank's `bytes`, as MPI's ints.
void layout(const std::vector<long long>& sizes, std::vector<int>& counts, std::vector<int>& displs,
            std::size_t& total) {
  counts.resize(sizes.size());
  displs.resize(sizes.size());
  total = 0;
  for (std::size_t r = 0; r < sizes.size(); ++r) {
    counts[r] = as_int(static_cast<std::size_t>(sizes[r]), "gather");
    displs[r] = as_int(total, "gather");
    total += static_cast<std::size_t>(sizes[r]);
  }
  as_int(total, "gather");
}

}  // namespace

int rank(MPI_Comm comm) {
  int r = 0;
  MPI_Comm_rank(comm, &r);
  return r;
}

int size(MPI_Comm comm) {
  int s = 1;
  MPI_Comm_size(comm, &s);
  return s;
}

double wall_seconds() {
  return MPI_Wtime();
}

void max_in_place(MPI_Comm comm, double* values, int n) {
  MPI_Allreduce(MPI_IN_PLACE, values, n, MPI_DOUBLE, MPI_MAX, comm);
}

void min_in_place(MPI_Comm comm, double* values, int n) {
  MPI_Allreduce(MPI_IN_PLACE, values, n, MPI_DOUBLE, MPI_MIN, comm);
}

void sum_in_place(MPI_Comm comm, long long* values, int n) {
  MPI_Allreduce(MPI_IN_PLACE, values, n, MPI_LONG_LONG, MPI_SUM, comm);
}

long long max_of(MPI_Comm comm, long long local) {
  long long out = 0;
  MPI_Allreduce(&local, &out, 1, MPI_LONG_LONG, MPI_MAX, comm);
  return out;
}

long long min_of(MPI_Comm comm, long long local) {
  long long out = 0;
  MPI_Allreduce(&local, &out, 1, MPI_LONG_LONG, MPI_MIN, comm);
  return out;
}

void max_to_root(MPI_Comm comm, const float* local, float* out, int n, int root) {
  MPI_Reduce(local, out, n, MPI_FLOAT, MPI_MAX, root, comm);
}

void sum_in_place(MPI_Comm comm, double* values, int n) {
  MPI_Allreduce(MPI_IN_PLACE, values, n, MPI_DOUBLE, MPI_SUM, comm);
}

void barrier(MPI_Comm comm) {
  MPI_Barrier(comm);
}

std::int64_t exclusive_prefix_sum(MPI_Comm comm, std::int64_t local) {
  std::int64_t below = 0;
  MPI_Exscan(&local, &below, 1, MPI_INT64_T, MPI_SUM, comm);
  return rank(comm) == 0 ? 0 : below;  // MPI leaves rank 0's result undefined
}

std::string broadcast(MPI_Comm comm, std::string text, int root) {
  unsigned long length = text.size();
  MPI_Bcast(&length, 1, MPI_UNSIGNED_LONG, root, comm);
  text.resize(length);
  broadcast_bytes(comm, text.data(), length, root);
  return text;
}

void broadcast_bytes(MPI_Comm comm, void* data, std::size_t bytes, int root) {
  if (bytes > 0) MPI_Bcast(data, as_int(bytes, "broadcast"), MPI_BYTE, root, comm);
}

std::vector<unsigned char> gather_bytes(MPI_Comm comm, const void* data, std::size_t bytes,
                                        int root, std::vector<std::size_t>* counts) {
  const int n = size(comm), me = rank(comm);
  long long mine = static_cast<long long>(bytes);
  std::vector<long long> sizes(me == root ? n : 0);
  MPI_Gather(&mine, 1, MPI_LONG_LONG, sizes.data(), 1, MPI_LONG_LONG, root, comm);
  std::vector<int> rcounts, displs;
  std::size_t total = 0;
  if (me == root) layout(sizes, rcounts, displs, total);
  std::vector<unsigned char> out(total);
  unsigned char nothing = 0;
  MPI_Gatherv(bytes ? data : &nothing, as_int(bytes, "gather"), MPI_BYTE,
              out.empty() ? &nothing : out.data(), rcounts.data(), displs.data(), MPI_BYTE, root,
              comm);
  if (counts) counts->assign(sizes.begin(), sizes.end());
  return out;
}

std::vector<unsigned char> all_gather_bytes(MPI_Comm comm, const void* data, std::size_t bytes) {
  const int n = size(comm);
  long long mine = static_cast<long long>(bytes);
  std::vector<long long> sizes(n);
  MPI_Allgather(&mine, 1, MPI_LONG_LONG, sizes.data(), 1, MPI_LONG_LONG, comm);
  std::vector<int> counts, displs;
  std::size_t total = 0;
  layout(sizes, counts, displs, total);
  std::vector<unsigned char> out(total);
  unsigned char nothing = 0;
  MPI_Allgatherv(bytes ? data : &nothing, as_int(bytes, "all_gather"), MPI_BYTE,
                 out.empty() ? &nothing : out.data(), counts.data(), displs.data(), MPI_BYTE, comm);
  return out;
}

}  // namespace gen4d::parallel
