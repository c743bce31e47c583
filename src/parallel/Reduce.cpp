#include "parallel/Reduce.hpp"

namespace gen4d::parallel {

Reducer::Reducer(MPI_Comm comm) : comm_(comm) {
  MPI_Comm_size(comm, &size_);
}

void Reducer::sum(const ExactSum* local, double* global, std::size_t n) {
  send_.resize(2 * n);
  recv_.resize(2 * n * static_cast<std::size_t>(size_));
  for (std::size_t i = 0; i < n; ++i) {
    send_[2 * i] = local[i].hi;
    send_[2 * i + 1] = local[i].lo;
  }
  MPI_Allgather(send_.data(), static_cast<int>(2 * n), MPI_DOUBLE, recv_.data(),
                static_cast<int>(2 * n), MPI_DOUBLE, comm_);
  for (std::size_t i = 0; i < n; ++i) {
    ExactSum acc;
    for (int r = 0; r < size_; ++r) {
      acc.add(recv_[2 * n * r + 2 * i]);
      acc.add(recv_[2 * n * r + 2 * i + 1]);
    }
    global[i] = acc.value();
  }
}

double Reducer::sum(double local) {
  ExactSum s;
  s.add(local);
  double g = 0;
  sum(&s, &g, 1);
  return g;
}

long long Reducer::sum(long long local) {
  long long g = 0;
  MPI_Allreduce(&local, &g, 1, MPI_LONG_LONG, MPI_SUM, comm_);
  return g;
}

double Reducer::max(double local) {
  double g = 0;
  MPI_Allreduce(&local, &g, 1, MPI_DOUBLE, MPI_MAX, comm_);
  return g;
}

ExactSum masked_dot(const double* a, const double* b, const unsigned char* mask, std::size_t n,
                    int dof) {
  ExactSum s;
  for (std::size_t i = 0; i < n; ++i) {
    if (mask && !mask[i]) continue;
    for (int c = 0; c < dof; ++c) s.add(a[i * dof + c] * b[i * dof + c]);
  }
  return s;
}

}  // namespace gen4d::parallel
