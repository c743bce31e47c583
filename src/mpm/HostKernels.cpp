// Built with -ffp-contract=off (src/CMakeLists.txt): the AVX2 copies round every product and sum
// on its own, as the baseline copies and a GPU (--fmad=false) do.
#include "mpm/HostKernels.hpp"

#include <cstdlib>
#include <cstring>

namespace gen4d::mpm::host {

namespace {

inline void p2g_loop(const kernels::P2GArgs& a, const long* order, long b, long e, double* grid) {
  const auto add = [](double* g, const auto& q) { kernels::add_lanes(g, q); };
  if (order)
    for (long q = b; q < e; ++q) kernels::p2g_particle(a, order[q], grid, add);
  else
    for (long i = b; i < e; ++i) kernels::p2g_particle(a, i, grid, add);
}

inline void bound_loop(const kernels::P2GArgs& a, long b, long e, double* bound) {
  double m = 0, p = 0;
  for (long i = b; i < e; ++i) {
    double q[2];
    kernels::p2g_bound(a, i, q);
    m = kernels::max_of(m, q[0]);
    p = kernels::max_of(p, q[1]);
  }
  bound[0] = m;
  bound[1] = p;
}

inline void g2p_loop(const kernels::G2PArgs& a, long b, long e, const kernels::GuardArgs* guard,
                     std::uint8_t* status) {
  if (guard)
    for (long i = b; i < e; ++i) {
      kernels::g2p_particle(a, i);
      status[i] = kernels::guard_particle(*guard, i);
    }
  else
    for (long i = b; i < e; ++i) kernels::g2p_particle(a, i);
}

__attribute__((target("avx512f"), flatten)) void p2g_avx512(const kernels::P2GArgs& a,
                                                            const long* order, long b, long e,
                                                            double* grid) {
  p2g_loop(a, order, b, e, grid);
}

__attribute__((target("avx2"), flatten)) void p2g_avx2(const kernels::P2GArgs& a, const long* order,
                                                       long b, long e, double* grid) {
  p2g_loop(a, order, b, e, grid);
}

__attribute__((flatten)) void p2g_baseline(const kernels::P2GArgs& a, const long* order, long b,
                                           long e, double* grid) {
  p2g_loop(a, order, b, e, grid);
}

__attribute__((target("avx512f"), flatten)) void bound_avx512(const kernels::P2GArgs& a, long b,
                                                              long e, double* bound) {
  bound_loop(a, b, e, bound);
}

__attribute__((target("avx2"), flatten)) void bound_avx2(const kernels::P2GArgs& a, long b, long e,
                                                         double* bound) {
  bound_loop(a, b, e, bound);
}

__attribute__((flatten)) void bound_baseline(const kernels::P2GArgs& a, long b, long e,
                                             double* bound) {
  bound_loop(a, b, e, bound);
}

__attribute__((target("avx512f"), flatten)) void g2p_avx512(const kernels::G2PArgs& a, long b,
                                                            long e, const kernels::GuardArgs* guard,
                                                            std::uint8_t* status) {
  g2p_loop(a, b, e, guard, status);
}

__attribute__((target("avx2"), flatten)) void g2p_avx2(const kernels::G2PArgs& a, long b, long e,
                                                       const kernels::GuardArgs* guard,
                                                       std::uint8_t* status) {
  g2p_loop(a, b, e, guard, status);
}

__attribute__((flatten)) void g2p_baseline(const kernels::G2PArgs& a, long b, long e,
                                           const kernels::GuardArgs* guard, std::uint8_t* status) {
  g2p_loop(a, b, e, guard, status);
}

}  // namespace

Isa best_isa() {
  static const Isa best = [] {
    const char* env = std::getenv("GEN4D_MPM_ISA");
    if (env && std::strcmp(env, "baseline") == 0) return Isa::kBaseline;
    if (env && std::strcmp(env, "avx2") == 0 && __builtin_cpu_supports("avx2")) return Isa::kAvx2;
    return __builtin_cpu_supports("avx512f") ? Isa::kAvx512
           : __builtin_cpu_supports("avx2")  ? Isa::kAvx2
                                             : Isa::kBaseline;
  }();
  return best;
}

namespace {
//! `isa` lowered to what this CPU supports.
Isa usable(Isa isa) {
  if (isa == Isa::kAvx512 && __builtin_cpu_supports("avx512f")) return Isa::kAvx512;
  if (isa >= Isa::kAvx2 && __builtin_cpu_supports("avx2")) return Isa::kAvx2;
  return Isa::kBaseline;
}

//! The copy of a loop for `isa` (the copies are indexed by Isa's values).
template <class Fn>
Fn pick(Isa isa, Fn baseline, Fn avx2, Fn avx512) {
  const Fn by_isa[] = {baseline, avx2, avx512};
  return by_isa[static_cast<int>(usable(isa))];
}
}  // namespace

void p2g_bound(const kernels::P2GArgs& a, long b, long e, double* bound, Isa isa) {
  pick(isa, &bound_baseline, &bound_avx2, &bound_avx512)(a, b, e, bound);
}

void p2g(const kernels::P2GArgs& a, const long* order, long b, long e, double* grid, Isa isa) {
  pick(isa, &p2g_baseline, &p2g_avx2, &p2g_avx512)(a, order, b, e, grid);
}

void g2p(const kernels::G2PArgs& a, long b, long e, const kernels::GuardArgs* guard,
         std::uint8_t* status, Isa isa) {
  if (!a.advance) guard = nullptr;
  pick(isa, &g2p_baseline, &g2p_avx2, &g2p_avx512)(a, b, e, guard, status);
}

}  // namespace gen4d::mpm::host
