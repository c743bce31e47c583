//! Instruction sets of the diagnose model's hand-vectorised kernels. A kernel's body is one
//! always-inlined source, built into one entry point per instruction set with GCC/Clang target
//! attributes (x86-64 only; elsewhere the baseline build is the only one), and picked at run
//! time. The files holding them are compiled with -ffp-contract=off, so every build rounds
//! exactly as the scalar code does.
#pragma once

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#if defined(__x86_64__) && defined(__GNUC__)
#define GEN4D_X86_ISAS 1
#define GEN4D_ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define GEN4D_X86_ISAS 0
#define GEN4D_ALWAYS_INLINE inline
#endif

namespace gen4d::forward {

// Four double lanes (a 256-bit vector where the build has AVX, else two 128-bit halves). The
// helpers taking and returning them are always inlined, so no call passes one in a register
// whose width depends on the instruction set (GCC's -Wpsabi note is about such calls).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wpsabi"
#endif
#if defined(__GNUC__)
typedef double V4 __attribute__((vector_size(32)));
#else
struct V4 {
  double v[4];
  friend V4 operator+(V4 a, const V4& b) {
    for (int i = 0; i < 4; ++i) a.v[i] += b.v[i];
    return a;
  }
  friend V4 operator-(V4 a, const V4& b) {
    for (int i = 0; i < 4; ++i) a.v[i] -= b.v[i];
    return a;
  }
  friend V4 operator*(V4 a, double s) {
    for (int i = 0; i < 4; ++i) a.v[i] *= s;
    return a;
  }
};
#endif
GEN4D_ALWAYS_INLINE V4 load4(const double* p) {
  V4 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
GEN4D_ALWAYS_INLINE void store4(double* p, const V4& v) {
  std::memcpy(p, &v, sizeof v);
}
GEN4D_ALWAYS_INLINE V4 splat4(double x) {
  return V4{x, x, x, x};
}

//! "baseline", then "avx2" and "avx512f" where this CPU (and build) has them.
inline std::vector<std::string> cpu_isas() {
  std::vector<std::string> out{"baseline"};
#if GEN4D_X86_ISAS
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx2")) out.emplace_back("avx2");
  if (__builtin_cpu_supports("avx512f")) out.emplace_back("avx512f");
#endif
  return out;
}

//! A kernel's table of entry points per instruction set (Table has a `const char* isa`) and the
//! one in use: AVX2 where the CPU has it (on the AMD EPYC measured, the AVX-512 builds were no
//! faster: bench_diagnose --isa), else AVX-512, else the baseline; switchable for tests and
//! benchmarks (not thread-safe).
template <class Table>
class IsaDispatch {
 public:
  //! builds: the kernel's tables, the baseline's first; what: the kernel's name for errors.
  IsaDispatch(std::vector<const Table*> builds, const char* what)
      : builds_(std::move(builds)), what_(what), use_(builds_.front()) {
    for (const char* want : {"avx512f", "avx2"})
      if (const Table* t = runnable(want)) use_ = t;
  }
  const Table& operator*() const { return *use_; }
  const Table* operator->() const { return use_; }
  //! The builds this CPU runs, the baseline first.
  std::vector<std::string> isas() const {
    std::vector<std::string> out;
    for (const Table* t : builds_)
      if (runnable(t->isa)) out.emplace_back(t->isa);
    return out;
  }
  //! std::invalid_argument for a build this CPU or the kernel lacks.
  void set(const std::string& isa) {
    const Table* t = runnable(isa);
    if (!t)
      throw std::invalid_argument(std::string(what_) + ": instruction set '" + isa +
                                  "' is not supported by this CPU or build");
    use_ = t;
  }

 private:
  const Table* runnable(const std::string& isa) const {
    const auto cpu = cpu_isas();
    if (std::find(cpu.begin(), cpu.end(), isa) == cpu.end()) return nullptr;
    for (const Table* t : builds_)
      if (isa == t->isa) return t;
    return nullptr;
  }
  std::vector<const Table*> builds_;
  const char* what_;
  const Table* use_;
};

}  // namespace gen4d::forward
