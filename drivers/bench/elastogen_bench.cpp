// bench_elastogen — throughput of ElastoGen's hot kernels, printed as JSON, with the
// machine's STREAM-triad bandwidth measured in the same run as the baseline.
//
// Sample runs:
//   build/drivers/bench_elastogen --cells 48
//   mpirun -np 2 build/drivers/bench_elastogen --cells 96 --sweeps 50
//
// Description:
//   1. STREAM triad a = b + s c over arrays far larger than the caches (best of 5), per rank
//      and summed over ranks: the memory bandwidth the sweeps can at best reach.
//   2. A cube of cells^3 voxels: damped-Jacobi sweeps of the global step (the fused
//      stencil + update kernel and the halo exchange), timed alone. Reports node updates/s and
//      the bytes/s implied by the minimal traffic of one sweep, and that bandwidth as a
//      fraction of STREAM; and the same for the unfused sweep (operator pass, then update
//      pass) as the baseline, timed in the same run.
//   3. The local step (internal forces: per voxel the eight Gauss-point gradients, stresses and
//      node forces) on the same cube, deformed: voxel updates/s of the solver's path (factored
//      stencil, Newton polar rotation, threaded) and, as the in-run baseline, of the reference
//      path it replaced (HexStencil's 8 x 8 corner loops, the law's SVD, one thread).
//   4. One ElastoGen time step (local step + sweeps) for steps/s at this size.
//   5. With a CUDA device: the same sweeps on the GPU (SweepDevice), bandwidth by the same
//      traffic model against the device's nominal and measured (triad) bandwidth;
//      "gpu": "skipped: <why>" otherwise.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "core/Deck.hpp"
#include "core/DeckText.hpp"
#include "core/Device.hpp"
#include "core/Log.hpp"
#include "core/ParallelFor.hpp"
#include "elastogen/GlobalSolver.hpp"
#include "elastogen/LocalKernels.hpp"
#include "elastogen/Simulation.hpp"
#include "elastogen/SweepDevice.hpp"
#include "materials/Arap.hpp"
#include "bench/Stream.hpp"
#include "validation/DriverCommon.hpp"

using namespace gen4d;

namespace {

Config cube(int cells, int sweeps) {
  const double h = 1.0 / cells;
  BeamDeck b;
  b.gravity = Vec3d{0, 0, -9.81};
  b.voxel_size = h;
  b.hi = {1, 1, 1};
  b.youngs_modulus = 1e5;
  b.solver.set("max_sweeps", sweeps).set("inner_tolerance", 1e-300);
  b.fixed_hi = {1, 1, 0.5 * h};
  return parse_deck(b.text().str(), "<bench cube>", ".");
}

//! The unfused sweep (operator pass, then update pass), timed as the in-run baseline of
//! the fused kernel. Returns seconds (max over ranks) for `sweeps` sweeps with halo exchanges.
double unfused_sweeps(elastogen::Simulation& sim, elastogen::GlobalSolver& solver,
                      const std::vector<double>& r, int sweeps, double omega) {
  elastogen::VoxelSystem& sys = sim.system();
  const double k = sim.dynamics().stiffness(), inv_dt2 = 1.0 / (0.01 * 0.01);
  std::vector<double> diag;
  sys.diagonal(k, inv_dt2, diag);
  std::vector<double> delta = r, ad = r, res = r;
  std::fill(delta.begin(), delta.end(), 0.0);
  const auto& free = sys.free_mask();
  MPI_Barrier(MPI_COMM_WORLD);
  const double t0 = MPI_Wtime();
  for (int s = 0; s < sweeps; ++s) {
    solver.halo().gather(delta.data());
    sys.apply(k, inv_dt2, delta.data(), ad.data());
    elastogen::for_owned(sys.owned(), sys.ghosted(), [&](std::size_t n, long, long, long) {
      if (!free[n]) return;
      for (int d = 0; d < 3; ++d) {
        const double rr = r[3 * n + d] - ad[3 * n + d];
        res[3 * n + d] = rr;
        delta[3 * n + d] += omega * rr / diag[n];
      }
    });
  }
  double t = MPI_Wtime() - t0, tmax = 0;
  MPI_Allreduce(&t, &tmax, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
  volatile double sink = delta[delta.size() / 2];
  (void)sink;
  return tmax;
}

//! The reference local step (the form the solver's path replaced): per voxel and Gauss
//! point, F from HexStencil's corner loop, the law's SVD stress, the corner-loop transpose;
//! serial. Returns the rank-local energy so the work is not optimised away.
double reference_local_step(elastogen::VoxelSystem& sys, const materials::Arap& law,
                            const double* x, std::vector<double>& cell_forces) {
  const elastogen::HexStencil& s = elastogen::HexStencil::get();
  const parallel::Box& C = sys.cells();
  const parallel::Box& G = sys.ghosted();
  const double inv_h = 1.0 / sys.h(), w = sys.h() * sys.h() * sys.h() / 8.0;
  long offset[8];
  for (int m = 0; m < 8; ++m)
    offset[m] = static_cast<long>(
        G.index(G.start[0] + (m & 1), G.start[1] + ((m >> 1) & 1), G.start[2] + ((m >> 2) & 1)));
  cell_forces.assign(24 * C.size(), 0.0);
  double energy = 0;
  for (long ck = C.start[2]; ck < C.start[2] + C.count[2]; ++ck)
    for (long cj = C.start[1]; cj < C.start[1] + C.count[1]; ++cj)
      for (long ci = C.start[0]; ci < C.start[0] + C.count[0]; ++ci) {
        const std::size_t c = C.index(ci, cj, ck);
        if (!sys.occupancy()[c]) continue;
        const std::size_t base = G.index(ci, cj, ck);
        double xe[8][3], fe[8][3] = {};
        for (int m = 0; m < 8; ++m)
          for (int a = 0; a < 3; ++a) xe[m][a] = x[3 * (base + offset[m]) + a];
        for (int q = 0; q < 8; ++q) {
          materials::Mat3 F, P;
          elastogen::deformation_gradient(s, q, xe, inv_h, F.a);
          energy += w * law.energy_and_pk1(F, P);
          elastogen::add_node_forces(s, q, P.a, w * inv_h, fe);
        }
        for (int m = 0; m < 8; ++m)
          for (int a = 0; a < 3; ++a) cell_forces[24 * c + 3 * m + a] = fe[m][a];
      }
  return energy;
}

//! Max over ranks of the seconds f() takes, best of `reps`.
template <class F>
double timed(int reps, const F& f) {
  double best = 1e300;
  for (int r = 0; r < reps; ++r) {
    MPI_Barrier(MPI_COMM_WORLD);
    const double t0 = MPI_Wtime();
    f();
    double t = MPI_Wtime() - t0, tmax = 0;
    MPI_Allreduce(&t, &tmax, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
    best = std::min(best, tmax);
  }
  return best;
}

//! The GPU section's JSON value: sweeps on the device, or why there are none.
std::string gpu_sweeps(elastogen::Simulation& sim, const std::vector<double>& r, int sweeps,
                       double omega, double bytes_per_node) {
#if defined(GEN4D_CUDA)
  if (!exec::use_device()) return fmt::format("\"skipped: {}\"", exec::device_description());
  elastogen::VoxelSystem& sys = sim.system();
  const double k = sim.dynamics().stiffness(), inv_dt2 = 1.0 / (0.01 * 0.01);
  std::vector<double> diag, d(r.size(), 0.0);
  sys.diagonal(k, inv_dt2, diag);
  const auto kern =
      sys.jacobi_kernel(k, inv_dt2, omega, r.data(), diag.data(), sys.mass().data(),
                        sys.free_mask().data(), sys.adjacency().data(), nullptr, nullptr, nullptr);
  elastogen::DeviceJacobi gpu(kern, sys.ghosted().size());
  gpu.set(r.data(), d.data());
  gpu.sweep(2);  // warm-up
  double best = 1e300;
  for (int rep = 0; rep < 3; ++rep) best = std::min(best, gpu.sweep(sweeps));
  // Ranks sweep their own boxes on their own devices: rates add up, the slowest sets time.
  double tmax = 0, local_nodes = 0, nodes = 0;
  MPI_Allreduce(&best, &tmax, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
  elastogen::for_owned(sys.owned(), sys.ghosted(),
                       [&](std::size_t n, long, long, long) { local_nodes += sys.free_mask()[n]; });
  MPI_Allreduce(&local_nodes, &nodes, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  const double hbm = elastogen::device_memory_bandwidth();
  const double triad = elastogen::device_stream_triad(std::size_t{1} << 27);
  const double updates = nodes * sweeps / tmax, bw = updates * bytes_per_node;
  int ranks = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &ranks);
  return fmt::format(
      "{{\"device\": \"{}\", \"sweeps\": {}, \"sweep_seconds\": {:.5f}, "
      "\"node_updates_per_s\": {:.4e}, \"sweep_GBps\": {:.1f}, \"hbm_nominal_GBps\": {:.1f}, "
      "\"fraction_of_hbm\": {:.3f}, \"device_triad_GBps\": {:.1f}, "
      "\"fraction_of_device_triad\": {:.3f}}}",
      exec::device_description(), sweeps, tmax, updates, bw / 1e9, ranks * hbm / 1e9,
      bw / (ranks * hbm), ranks * triad / 1e9, bw / (ranks * triad));
#else
  (void)sim, (void)r, (void)sweeps, (void)omega, (void)bytes_per_node;
  return "\"skipped: built without the CUDA back end (GEN4D_CUDA=OFF)\"";
#endif
}

int run(int cells, int sweeps, long stream_n) {
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  const double stream = bench::stream_triad(static_cast<std::size_t>(stream_n));
  const Config cfg = cube(cells, sweeps);
  log::set_quiet(true);
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
  log::set_quiet(false);
  elastogen::VoxelSystem& sys = sim.system();
  PhaseTimers timers;
  elastogen::GlobalSolver solver(sys, cfg.solver, sim.dynamics().stiffness(), cfg.dt, timers);
  std::vector<double> r(3 * sys.ghosted().size(), 0.0), delta;
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(-1, 1);
  for (std::size_t i = 0; i < r.size(); ++i) r[i] = sys.free_mask()[i / 3] ? u(rng) : 0.0;
  const auto st = solver.solve(r, delta);
  double local[2] = {timers.total("sweeps") + timers.total("halo"), timers.total("halo")};
  double tmax[2];
  MPI_Allreduce(local, tmax, 2, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
  const double base_s = unfused_sweeps(sim, solver, r, st.sweeps, cfg.solver.jacobi_omega);
  const double nodes = static_cast<double>(sys.global_free_nodes());
  // Minimal traffic per node and sweep. Fused: delta read and write (48 B), r (24 B),
  // diagonal (8 B), masks (2 B), the residual every 8th sweep (3 B). Unfused: delta read +
  // write (48 B), A delta write + read (48 B), r (24 B), diagonal and mass (16 B), masks (2 B).
  const double bytes_fused = 85.0, bytes_unfused = 138.0;
  const double updates = nodes * st.sweeps / tmax[0];
  const double base_updates = nodes * st.sweeps / base_s;
  // Local step on the cube deformed by a smooth bend plus noise (rotations ~0.2 rad).
  std::vector<double> x = sim.dynamics().x(), f(x.size(), 0.0), cell_forces;
  for (std::size_t q = 0; q < x.size(); q += 3) {
    const double th = 0.2 * x[q];
    const double px = x[q], pz = x[q + 2];
    x[q] = px * std::cos(th) + pz * std::sin(th) + 1e-4 * u(rng);
    x[q + 1] += 1e-4 * u(rng);
    x[q + 2] = -px * std::sin(th) + pz * std::cos(th) + 1e-4 * u(rng);
  }
  const auto arap =
      materials::Arap::from_young_poisson(cfg.material.youngs_modulus, cfg.material.poisson_ratio);
  double sink = 0;
  const double local_s = timed(3, [&] {
    sink += sys.internal_forces(elastogen::ArapPolarStress{arap}, x.data(), f.data()).value();
  });
  const double ref_s =
      timed(2, [&] { sink += reference_local_step(sys, arap, x.data(), cell_forces); });
  double voxels = 0, local_voxels = 0;
  for (std::uint8_t o : sys.occupancy()) local_voxels += o != 0;
  MPI_Allreduce(&local_voxels, &voxels, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  const std::string gpu = gpu_sweeps(sim, r, st.sweeps, cfg.solver.jacobi_omega, bytes_fused);
  const double t0 = MPI_Wtime();
  const auto step = sim.dynamics().step(0.0);
  const double step_s = MPI_Wtime() - t0;
  if (rank == 0)
    std::printf(
        "{\n  \"ranks\": %d,\n  \"threads_per_rank\": %d,\n  \"stream_triad_GBps\": %.3f,\n"
        "  \"cells\": %d,\n"
        "  \"free_nodes\": %.0f,\n  \"dofs\": %.0f,\n  \"sweeps\": %d,\n"
        "  \"sweep_seconds\": %.4f,\n  \"halo_seconds\": %.4f,\n"
        "  \"node_updates_per_s\": %.4e,\n  \"sweep_GBps\": %.3f,\n"
        "  \"fraction_of_stream\": %.3f,\n"
        "  \"baseline_unfused\": {\"node_updates_per_s\": %.4e, \"sweep_GBps\": %.3f, "
        "\"fraction_of_stream\": %.3f},\n  \"speedup_fused_over_unfused\": %.3f,\n"
        "  \"local_step\": {\"voxels\": %.0f, \"seconds\": %.4f, \"voxel_updates_per_s\": %.4e, "
        "\"baseline_svd_stencil\": {\"seconds\": %.4f, \"voxel_updates_per_s\": %.4e}, "
        "\"speedup\": %.2f},\n"
        "  \"step_seconds\": %.3f,\n  \"step_loops\": %d,\n  \"step_sweeps\": %ld,\n"
        "  \"gpu\": %s\n}\n",
        size, exec::host_threads(), stream / 1e9, cells, nodes, 3 * nodes, st.sweeps, tmax[0],
        tmax[1], updates, updates * bytes_fused / 1e9, updates * bytes_fused / stream, base_updates,
        base_updates * bytes_unfused / 1e9, base_updates * bytes_unfused / stream,
        updates / base_updates, voxels, local_s, voxels / local_s, ref_s, voxels / ref_s,
        ref_s / local_s, step_s, step.outer, step.sweeps, gpu.c_str());
  volatile double keep = sink;
  (void)keep;
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  int cells = 48, sweeps = 100;
  long stream_n = 20000000;
  return driver::main_with(
      argc, argv, "ElastoGen kernel throughput vs STREAM triad, as JSON",
      [&](CLI::App& app) {
        app.add_option("--cells", cells, "Cube of cells^3 voxels")->check(CLI::Range(4, 2000));
        app.add_option("--sweeps", sweeps, "Jacobi sweeps to time")->check(CLI::Range(1, 100000));
        app.add_option("--stream-n", stream_n, "STREAM array length per rank")
            ->check(CLI::Range(1000000L, 1000000000L));
      },
      [&] { return run(cells, sweeps, stream_n); });
}
