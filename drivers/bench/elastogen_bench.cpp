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
//   3. One ElastoGen time step (stencil + SVD + sweeps) for steps/s at this size.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <random>
#include <vector>

#include "core/Deck.hpp"
#include "core/Log.hpp"
#include "elastogen/GlobalSolver.hpp"
#include "elastogen/Simulation.hpp"
#include "bench/Stream.hpp"
#include "validation/DriverCommon.hpp"

using namespace gen4d;

namespace {

Config cube(int cells, int sweeps) {
  const double h = 1.0 / cells;
  return parse_deck(fmt::format(R"(
[simulation]
dt = 0.01
end_time = 0.01
gravity = [0.0, 0.0, -9.81]
[domain]
voxel_size = {}
padding = 0
[[geometry]]
type = "box"
lo = [0.0, 0.0, 0.0]
hi = [1.0, 1.0, 1.0]
[material]
youngs_modulus = 1e5
poisson_ratio = 0.3
density = 1000.0
[solver]
max_sweeps = {}
inner_tolerance = 1e-300
[[fixed]]
lo = [-1.0, -1.0, -1.0]
hi = [1.0, 1.0, {}]
)",
                                h, sweeps, 0.5 * h),
                    "<bench cube>", ".");
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
  const double t0 = MPI_Wtime();
  const auto step = sim.dynamics().step(0.0);
  const double step_s = MPI_Wtime() - t0;
  if (rank == 0)
    std::printf(
        "{\n  \"ranks\": %d,\n  \"stream_triad_GBps\": %.3f,\n  \"cells\": %d,\n"
        "  \"free_nodes\": %.0f,\n  \"dofs\": %.0f,\n  \"sweeps\": %d,\n"
        "  \"sweep_seconds\": %.4f,\n  \"halo_seconds\": %.4f,\n"
        "  \"node_updates_per_s\": %.4e,\n  \"sweep_GBps\": %.3f,\n"
        "  \"fraction_of_stream\": %.3f,\n"
        "  \"baseline_unfused\": {\"node_updates_per_s\": %.4e, \"sweep_GBps\": %.3f, "
        "\"fraction_of_stream\": %.3f},\n  \"speedup_fused_over_unfused\": %.3f,\n"
        "  \"step_seconds\": %.3f,\n  \"step_loops\": %d,\n  \"step_sweeps\": %ld\n}\n",
        size, stream / 1e9, cells, nodes, 3 * nodes, st.sweeps, tmax[0], tmax[1], updates,
        updates * bytes_fused / 1e9, updates * bytes_fused / stream, base_updates,
        base_updates * bytes_unfused / 1e9, base_updates * bytes_unfused / stream,
        updates / base_updates, step_s, step.outer, step.sweeps);
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
