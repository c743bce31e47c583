#include "parallel/Reduce.hpp"

#include <cmath>

namespace gen4d::parallel {

void ExactSum::normalize() {
  for (int i = 0; i + 1 < kDigits; ++i) {
    const std::int64_t carry = digit_[i] >> 32;  // floor division: digit_[i] keeps [0, 2^32)
    digit_[i] -= carry * (std::int64_t{1} << 32);
    digit_[i + 1] += carry;
  }
  pending_ = 0;
}

void ExactSum::add(const ExactSum& o) {
  ExactSum c = o;
  c.normalize();
  normalize();
  for (int i = 0; i < kDigits; ++i) digit_[i] += c.digit_[i];
  special_ += o.special_;
  pending_ = 1;
}

double ExactSum::value() const {
  if (special_ != 0.0 || std::isnan(special_)) return special_;
  ExactSum c = *this;
  c.normalize();
  const bool negative = c.digit_[kDigits - 1] < 0;
  if (negative) {
    for (auto& d : c.digit_) d = -d;
    c.normalize();
  }
  int top = kDigits - 1;
  while (top >= 0 && c.digit_[top] == 0) --top;
  if (top < 0) return 0.0;
  // The top three digits as one integer (at least 2^64 when top >= 2, so 53-bit rounding
  // happens well above bit 0), with the lower digits folded into a sticky bit.
  const int lo = top >= 2 ? top - 2 : 0;
  unsigned __int128 m = 0;
  for (int i = top; i >= lo; --i) m = (m << 32) | static_cast<std::uint64_t>(c.digit_[i]);
  bool sticky = false;
  for (int i = 0; i < lo; ++i) sticky = sticky || c.digit_[i] != 0;
  if (sticky) m |= 1;
  const double r = std::ldexp(static_cast<double>(m), 32 * lo - 1074);
  return negative ? -r : r;
}

void ExactSum::pack(std::int64_t* out) const {
  ExactSum c = *this;
  c.normalize();
  for (int i = 0; i < kDigits; ++i) out[i] = c.digit_[i];
  std::memcpy(&out[kDigits], &special_, sizeof special_);
}

void ExactSum::unpack_add(const std::int64_t* in) {
  if (pending_ > 0) normalize();
  for (int i = 0; i < kDigits; ++i) digit_[i] += in[i];
  double s;
  std::memcpy(&s, &in[kDigits], sizeof s);
  special_ += s;
  pending_ = 1;
}

Reducer::Reducer(MPI_Comm comm) : comm_(comm) {
  MPI_Comm_size(comm, &size_);
}

void Reducer::sum(const ExactSum* local, double* global, std::size_t n) {
  const std::size_t w = ExactSum::kWords;
  send_.resize(w * n);
  recv_.resize(w * n * static_cast<std::size_t>(size_));
  for (std::size_t i = 0; i < n; ++i) local[i].pack(&send_[w * i]);
  MPI_Allgather(send_.data(), static_cast<int>(w * n), MPI_INT64_T, recv_.data(),
                static_cast<int>(w * n), MPI_INT64_T, comm_);
  for (std::size_t i = 0; i < n; ++i) {
    ExactSum acc;
    for (int r = 0; r < size_; ++r) acc.unpack_add(&recv_[w * n * r + w * i]);
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
