//! Decomposition-independent global sums: each value is accumulated in double-double
//! (error-free TwoSum), so the rounded result does not depend on how the terms were split
//! across ranks or ordered inside one — the basis of bit-identical runs at any rank count.
#pragma once

#include <mpi.h>

#include <cstddef>
#include <vector>

namespace gen4d::parallel {

//! A compensated accumulator (hi + lo represents the running sum almost exactly).
struct ExactSum {
  double hi = 0.0, lo = 0.0;
  void add(double v) {
    const double s = hi + v;
    const double bp = s - hi;
    const double err = (hi - (s - bp)) + (v - bp);
    hi = s;
    lo += err;
  }
  void add(const ExactSum& o) {
    add(o.hi);
    add(o.lo);
  }
  double value() const { return hi + lo; }
};

//! Fused reduction: sums n accumulators across the communicator in one collective.
//! Every rank receives the same n values.
class Reducer {
 public:
  explicit Reducer(MPI_Comm comm);
  //! One MPI_Allgather of all accumulators, then a fixed rank-order double-double sum.
  void sum(const ExactSum* local, double* global, std::size_t n);
  //! Convenience: plain doubles (each already a rank-local sum).
  double sum(double local);
  long long sum(long long local);
  double max(double local);
  MPI_Comm comm() const { return comm_; }

 private:
  MPI_Comm comm_;
  int size_ = 1;
  std::vector<double> send_, recv_;
};

//! Local dot product of two arrays restricted to entries with mask != 0 (if given),
//! accumulated exactly; `dof` values per mask entry.
ExactSum masked_dot(const double* a, const double* b, const unsigned char* mask, std::size_t n,
                    int dof);

}  // namespace gen4d::parallel
