//! Decomposition-independent global sums. Every term is added exactly into a fixed-point
//! superaccumulator (32-bit digits spanning the whole double range), so a sum is a function of
//! the multiset of its terms only — not of how they were split across ranks or ordered
//! inside one — and is rounded to a double once, at the end. This is the basis of
//! bit-identical runs at any rank count, even when a sum cancels to (almost) nothing.
#pragma once

#include <mpi.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <vector>

namespace gen4d::parallel {

//! Exact accumulator of doubles: value = sum_i digit[i] 2^(32 i - 1074); digits are signed
//! 64-bit with headroom, carried into canonical form every 2^30 additions and on demand.
//! Infinities and NaNs are summed separately in floating point and win in value().
class ExactSum {
 public:
  static constexpr int kDigits = 67;  //!< 2098 bits of range + one digit of carry room

  void add(double v) {
    std::uint64_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    const int exponent = static_cast<int>((bits >> 52) & 0x7FF);
    std::uint64_t mantissa = bits & ((std::uint64_t{1} << 52) - 1);
    if (exponent == 0x7FF) {
      special_ += v;
      return;
    }
    if (exponent == 0) {
      if (mantissa == 0) return;
    } else {
      mantissa |= std::uint64_t{1} << 52;
    }
    // v = +-mantissa 2^(e - 1075) with e >= 1: the mantissa's lowest bit is bit e - 1 above
    // 2^-1074.
    const int pos = (exponent == 0 ? 1 : exponent) - 1;
    const int d = pos >> 5;
    const unsigned __int128 m = static_cast<unsigned __int128>(mantissa) << (pos & 31);
    // Branch-free sign: (c ^ s) - s negates c when s = -1.
    const std::int64_t sg = -static_cast<std::int64_t>(bits >> 63);
    const auto lo = static_cast<std::uint64_t>(m);
    digit_[d] += (static_cast<std::int64_t>(lo & 0xFFFFFFFFu) ^ sg) - sg;
    digit_[d + 1] += (static_cast<std::int64_t>(lo >> 32) ^ sg) - sg;
    digit_[d + 2] += (static_cast<std::int64_t>(static_cast<std::uint64_t>(m >> 64)) ^ sg) - sg;
    if (++pending_ == kMaxPending) normalize();
  }
  void add(const ExactSum& o);
  //! The exact sum rounded to the nearest double (ties to even).
  double value() const;
  //! Carries every digit into [0, 2^32) except the signed top one.
  void normalize();

  //! Wire format for reductions: kDigits canonical digits, then the special sum's bits.
  static constexpr int kWords = kDigits + 1;
  void pack(std::int64_t* out) const;
  void unpack_add(const std::int64_t* in);

 private:
  static constexpr int kMaxPending = 1 << 30;
  std::array<std::int64_t, kDigits> digit_{};
  int pending_ = 0;
  double special_ = 0.0;
};

//! Fused reduction: sums n accumulators across the communicator in one collective.
//! Every rank receives the same n values.
class Reducer {
 public:
  explicit Reducer(MPI_Comm comm);
  //! One MPI_Allgather of all accumulators' digits, summed exactly, rounded once.
  void sum(const ExactSum* local, double* global, std::size_t n);
  //! Convenience: plain doubles (each already a rank-local sum).
  double sum(double local);
  long long sum(long long local);
  double max(double local);
  MPI_Comm comm() const { return comm_; }

 private:
  MPI_Comm comm_;
  int size_ = 1;
  std::vector<std::int64_t> send_, recv_;
};

//! Local dot product of two arrays restricted to entries with mask != 0 (if given),
//! accumulated exactly; `dof` values per mask entry.
ExactSum masked_dot(const double* a, const double* b, const unsigned char* mask, std::size_t n,
                    int dof);

}  // namespace gen4d::parallel
