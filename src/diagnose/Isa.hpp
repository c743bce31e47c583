//! Instruction sets of the diagnose model's hand-vectorised kernels. A kernel's body is one
//! always-inlined source, built into one entry point per instruction set with GCC/Clang target
//! attributes (x86-64 only; elsewhere the baseline build is the only one), and picked at run
//! time. The files holding them are compiled with -ffp-contract=off, so every build rounds
//! exactly as the scalar code does.
#pragma once

#include <string>
#include <vector>

#if defined(__x86_64__) && defined(__GNUC__)
#define GEN4D_X86_ISAS 1
#define GEN4D_ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define GEN4D_X86_ISAS 0
#define GEN4D_ALWAYS_INLINE inline
#endif

namespace gen4d::diagnose {

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

}  // namespace gen4d::diagnose
