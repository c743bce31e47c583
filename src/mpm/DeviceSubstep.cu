// CUDA instantiation of the MPM kernels (mpm/Kernels.hpp); no physics here.
#include <cstdint>

#include "core/DeviceArray.hpp"
#include "core/ParallelFor.hpp"
#include "mpm/DeviceSubstep.hpp"

namespace gen4d::mpm::device {

using exec::DeviceArray;

class Workspace {
 public:
  DeviceArray<double> x, v, C, F, tau, mass, vol0, pm, vel;
  DeviceArray<std::uint8_t> flag;
  DeviceArray<kernels::GridCondition> cond;
};

void WorkspaceDeleter::operator()(Workspace* w) const {
  delete w;
}

WorkspacePtr make_workspace() {
  return WorkspacePtr(new Workspace);
}

namespace {

//! Order-independent: every value is an integer multiple of the quantum.
struct AtomicAdd {
  template <int N>
  GEN4D_HD void operator()(double* g, const kernels::Lanes<N>& q) const {
#if defined(__CUDA_ARCH__)
    for (int k = 0; k < N; ++k) atomicAdd(g + k, q[k]);
#else
    kernels::add_lanes(g, q);
#endif
  }
};

//! Copies n host values into d and returns d's device pointer.
template <class T>
T* stage(DeviceArray<T>& d, const T* host, std::size_t n) {
  d.upload(host, n);
  return d.data();
}

void sync(const char* what) {
  exec::cuda_check(cudaGetLastError(), what);
  exec::cuda_check(cudaDeviceSynchronize(), what);
}

}  // namespace

void p2g(Workspace& w, const kernels::P2GArgs& args, long n, double* grid, long nodes) {
  const auto un = static_cast<std::size_t>(n);
  kernels::P2GArgs a = args;
  a.x = stage(w.x, args.x, 3 * un);
  a.v = stage(w.v, args.v, 3 * un);
  a.C = stage(w.C, args.C, 9 * un);
  a.tau = stage(w.tau, args.tau, 9 * un);
  a.mass = stage(w.mass, args.mass, un);
  a.vol0 = stage(w.vol0, args.vol0, un);
  a.flag = stage(w.flag, args.flag, un);
  w.pm.resize(4 * static_cast<std::size_t>(nodes));
  w.pm.zero();
  double* g = w.pm.data();
  exec::device_for(n, [=] __device__(long i) { kernels::p2g_particle(a, i, g, AtomicAdd{}); });
  sync("mpm p2g");
  w.pm.download(grid, 4 * static_cast<std::size_t>(nodes));
}

void grid_update(Workspace& w, const kernels::GridArgs& args, long nodes) {
  const auto un = static_cast<std::size_t>(nodes);
  w.vel.resize(3 * un);
  kernels::GridArgs a = args;
  a.pm = stage(w.pm, args.pm, 4 * un);
  a.vel = w.vel.data();
  a.cond = stage(w.cond, args.cond, static_cast<std::size_t>(args.ncond));
  exec::device_for(nodes, [=] __device__(long k) { kernels::grid_node(a, k); });
  sync("mpm grid update");
  w.vel.download(args.vel, 3 * un);
}

void g2p(Workspace& w, const kernels::G2PArgs& args, long n, long nodes) {
  const auto un = static_cast<std::size_t>(n);
  kernels::G2PArgs a = args;
  a.x = stage(w.x, args.x, 3 * un);
  a.v = stage(w.v, args.v, 3 * un);  // frozen particles keep their v and C
  a.C = stage(w.C, args.C, 9 * un);
  a.F = stage(w.F, args.F, 9 * un);
  a.flag = stage(w.flag, args.flag, un);
  a.vel = stage(w.vel, args.vel, 3 * static_cast<std::size_t>(nodes));
  exec::device_for(n, [=] __device__(long i) { kernels::g2p_particle(a, i); });
  sync("mpm g2p");
  w.x.download(args.x, 3 * un);
  w.v.download(args.v, 3 * un);
  w.C.download(args.C, 9 * un);
  w.F.download(args.F, 9 * un);
}

}  // namespace gen4d::mpm::device
