// The global step's Jacobi sweep on the GPU: SweepKernel.hpp's JacobiSweepKernel launched
// through exec::device_for, with the operator's arrays kept in device memory.
#include <cuda_runtime_api.h>

#include <cstdint>
#include <utility>

#include "core/DeviceArray.hpp"
#include "core/ParallelFor.hpp"
#include "elastogen/SweepDevice.hpp"
#include "elastogen/SweepKernel.hpp"

namespace gen4d::elastogen {

struct DeviceJacobi::Impl {
  JacobiSweepKernel kern;
  std::size_t nodes = 0;
  long values = 0;  //!< owned values, one thread each
  exec::DeviceArray<double> r, diag, mass, d0, d1, res;
  exec::DeviceArray<std::uint8_t> free, adj;
  bool current_is_d0 = true;
};

DeviceJacobi::DeviceJacobi(const JacobiSweepKernel& host, std::size_t nodes)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.kern = host;
  m.nodes = nodes;
  m.values = host.values();
  m.diag.upload(host.diag, nodes);
  m.mass.upload(host.mass, nodes);
  m.free.upload(host.free, nodes);
  m.adj.upload(host.adj, nodes);
  m.r.resize(3 * nodes);
  m.d0.resize(3 * nodes);
  m.d1.resize(3 * nodes);
  m.res.resize(3 * nodes);
  m.res.zero();
}

DeviceJacobi::~DeviceJacobi() = default;

void DeviceJacobi::set(const double* r, const double* d) {
  Impl& m = *impl_;
  m.r.upload(r, 3 * m.nodes);
  m.d0.upload(d, 3 * m.nodes);
  m.d1.upload(d, 3 * m.nodes);  // ghost values are read from either buffer
  m.current_is_d0 = true;
}

double DeviceJacobi::sweep(int sweeps) {
  Impl& m = *impl_;
  cudaEvent_t start, stop;
  exec::cuda_check(cudaEventCreate(&start), "cudaEventCreate");
  exec::cuda_check(cudaEventCreate(&stop), "cudaEventCreate");
  exec::cuda_check(cudaEventRecord(start), "cudaEventRecord");
  for (int s = 0; s < sweeps; ++s) {
    JacobiSweepKernel k = m.kern;
    k.r = m.r.data();
    k.diag = m.diag.data();
    k.mass = m.mass.data();
    k.free = m.free.data();
    k.adj = m.adj.data();
    k.d_old = m.current_is_d0 ? m.d0.data() : m.d1.data();
    k.d_new = m.current_is_d0 ? m.d1.data() : m.d0.data();
    k.res = s + 1 == sweeps ? m.res.data() : nullptr;
    exec::device_for(m.values, k);
    m.current_is_d0 = !m.current_is_d0;
  }
  exec::cuda_check(cudaGetLastError(), "Jacobi sweep launch");
  exec::cuda_check(cudaEventRecord(stop), "cudaEventRecord");
  exec::cuda_check(cudaEventSynchronize(stop), "Jacobi sweeps");
  float ms = 0;
  exec::cuda_check(cudaEventElapsedTime(&ms, start, stop), "cudaEventElapsedTime");
  cudaEventDestroy(start);
  cudaEventDestroy(stop);
  return 1e-3 * ms;
}

void DeviceJacobi::get(double* d, double* res) const {
  const Impl& m = *impl_;
  (m.current_is_d0 ? m.d0 : m.d1).download(d, 3 * m.nodes);
  if (res) m.res.download(res, 3 * m.nodes);
}

namespace {
struct Triad {
  double* a;
  const double* b;
  const double* c;
  double s;
  GEN4D_HD void operator()(long i) const { a[i] = b[i] + s * c[i]; }
};
}  // namespace

double device_memory_bandwidth() {
  int dev = 0, clock_khz = 0, bus_bits = 0;
  exec::cuda_check(cudaGetDevice(&dev), "cudaGetDevice");
  exec::cuda_check(cudaDeviceGetAttribute(&clock_khz, cudaDevAttrMemoryClockRate, dev),
                   "memory clock");
  exec::cuda_check(cudaDeviceGetAttribute(&bus_bits, cudaDevAttrGlobalMemoryBusWidth, dev),
                   "memory bus width");
  return 2.0 * 1e3 * clock_khz * (bus_bits / 8.0);
}

double device_stream_triad(std::size_t n) {
  exec::DeviceArray<double> a(n), b(n), c(n);
  a.zero();
  b.zero();
  c.zero();
  cudaEvent_t start, stop;
  exec::cuda_check(cudaEventCreate(&start), "cudaEventCreate");
  exec::cuda_check(cudaEventCreate(&stop), "cudaEventCreate");
  float best = 1e30f;
  for (int rep = 0; rep < 5; ++rep) {
    exec::cuda_check(cudaEventRecord(start), "cudaEventRecord");
    exec::device_for(static_cast<long>(n), Triad{a.data(), b.data(), c.data(), 3.0 + rep});
    exec::cuda_check(cudaEventRecord(stop), "cudaEventRecord");
    exec::cuda_check(cudaEventSynchronize(stop), "triad");
    float ms = 0;
    exec::cuda_check(cudaEventElapsedTime(&ms, start, stop), "cudaEventElapsedTime");
    best = ms < best ? ms : best;
  }
  cudaEventDestroy(start);
  cudaEventDestroy(stop);
  return 24.0 * static_cast<double>(n) / (1e-3 * best);
}

}  // namespace gen4d::elastogen
