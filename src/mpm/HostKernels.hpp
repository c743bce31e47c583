//! The host's loops over the MPM kernels (Kernels.hpp), compiled per instruction set: the AVX2
//! copy runs a node's four values in one instruction, the AVX-512 copy two nodes' eight. Every copy
//! rounds as the scalar kernels do (no fused multiply-adds), so the results are the same bits on
//! any CPU.
#pragma once

#include "mpm/Kernels.hpp"

namespace gen4d::mpm::host {

enum class Isa { kBaseline = 0, kAvx2 = 1, kAvx512 = 2 };

//! The best the CPU has; GEN4D_MPM_ISA=baseline or avx2 caps it (for comparisons).
Isa best_isa();

//! The largest p2g_bound of particles b..e into bound[0] (mass) and bound[1] (momentum);
//! frozen particles count too.
void p2g_bound(const kernels::P2GArgs& a, long b, long e, double* bound, Isa isa = best_isa());

//! P2G of particles order[b..e) (or b..e when `order` is null) into `grid`, plain additions:
//! the caller makes sure no other thread touches the same nodes.
void p2g(const kernels::P2GArgs& a, const long* order, long b, long e, double* grid,
         Isa isa = best_isa());

//! G2P of particles b..e; with `guard` (and a.advance), each particle's guard_particle status
//! right after its move, into status[i].
void g2p(const kernels::G2PArgs& a, long b, long e, const kernels::GuardArgs* guard = nullptr,
         std::uint8_t* status = nullptr, Isa isa = best_isa());

}  // namespace gen4d::mpm::host
