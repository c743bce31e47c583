//! The MPM substep's kernels on this rank's GPU (CUDA back end, GEN4D_CUDA=ON).
//
// The same kernels as the host path (mpm/Kernels.hpp), launched through exec::device_for in
// DeviceSubstep.cu. P2G adds with atomics: the contributions are integer multiples of the
// quantum, so the sums equal the host's in every bit, whatever the order. The host keeps the
// materials' return maps, the halo exchange, the guard and migration; the particle and grid
// arrays a phase needs are staged through host memory around each launch.
#pragma once

#if defined(GEN4D_CUDA)
#include <memory>

#include "mpm/Kernels.hpp"

namespace gen4d::mpm::device {

//! Device buffers reused across substeps (they grow, never shrink).
class Workspace;
struct WorkspaceDeleter {
  void operator()(Workspace* w) const;
};
using WorkspacePtr = std::unique_ptr<Workspace, WorkspaceDeleter>;
WorkspacePtr make_workspace();

//! P2G of n particles (host arrays in `args`) into `grid` (host, 4 values x `nodes`, zeroed).
void p2g(Workspace& w, const kernels::P2GArgs& args, long n, double* grid, long nodes);
//! Grid velocities (host `args.vel`, 3 x nodes) from the host P2G sums `args.pm`.
void grid_update(Workspace& w, const kernels::GridArgs& args, long nodes);
//! G2P of n particles; reads the host `args.vel` (3 x nodes), updates the host x, v, C, F.
void g2p(Workspace& w, const kernels::G2PArgs& args, long n, long nodes);

}  // namespace gen4d::mpm::device
#endif
