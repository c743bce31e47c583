// validate_convergence — accuracy of ElastoGen against the Newton reference as a function of
// the number of relaxation loops (seed paper App. G): a Neo-Hookean beam clamped at one end
// and twisted at the other (under gravity), with and without the subspace start, damped Jacobi
// and Chebyshev.
//
// Sample runs:
//   mpirun -np 2 build/drivers/validate_convergence
//   build/drivers/validate_convergence --steps 10 --csv convergence.csv
//   python3 drivers/validation/plot_convergence.py convergence.csv convergence.png
//
// Definitions:
//   loops L     RNN-2 relaxation sweeps per global step, a fixed count: solver.max_sweeps = L
//               with solver.inner_tolerance = 0 (no early stop). RNN-1 (the outer loop of
//               local targets and global steps) runs to its tolerance: relative change of x
//               below --outer-tolerance (default 1e-4), at most --max-outer loops, with its
//               usual Anderson acceleration (depth 5). The accuracy check's extra loops are off
//               (max_extra_outer = 0), so no loop is added behind L's back. Anderson stays on
//               because without it RNN-1 stops on a small relative change long before it
//               converges: with --anderson 0 (and outer tolerance 1e-3) every row sits at a
//               4.3 % error whatever L, which hides the loops' effect instead of isolating it.
//   error       trajectory error: max over steps and nodes of |x_E - x_N| (Euclidean, per
//               node) divided by the max over steps and nodes of the reference displacement
//               |x_N - X|. x_N: Newton's method (PETSc SNES, rtol 1e-10) on the same deck.
//   residual    seed-style error: the true implicit-Euler residual after the loops,
//               ||M(x-y)/dt^2 + grad E(x)|| / (||M(x-y)/dt^2|| + ||f_ext||) (StepStats.accuracy),
//               mean and max over the steps.
//
// Description:
//   1. Newton reference trajectory of the twisted beam (kept in memory, owned nodes per rank).
//   2. ElastoGen for L in {1, 3, 5, 20, 50} x subspace {K = 18, K = 0} x relaxation {jacobi,
//      chebyshev}: error, residual, sweeps and outer loops per step, wall time.
//   3. Plain Jacobi (K = 0, damped Jacobi): L = 50, 100, 200, ... (doubling, at most
//      --plain-cap) until its error reaches that of K = 18 Jacobi at L = 50; "did not reach"
//      if the cap comes first.
//   4. Exit 1 if K = 18 damped Jacobi at L = 50 is above --tolerance (default 1 %).
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "core/Deck.hpp"
#include "core/DeckText.hpp"
#include "core/Error.hpp"
#include "core/Log.hpp"
#include "elastogen/Simulation.hpp"
#include "validation/DriverCommon.hpp"

using namespace gen4d;

namespace {

struct Options {
  int steps = 40;
  double dt = 0.01, voxel = 0.025, youngs = 1e5, twist_deg = 180, tolerance = 0.01;
  double outer_tolerance = 1e-4;
  int max_outer = 500, plain_cap = 5000, anderson = 5;
  std::string csv;

  //! Declares the command-line options.
  void add(CLI::App& app) {
    app.add_option("--steps", steps, "Time steps")->check(CLI::Range(1, 100000));
    app.add_option("--dt", dt, "Time step in seconds")->check(CLI::PositiveNumber);
    app.add_option("--voxel", voxel, "Voxel size in metres")->check(CLI::PositiveNumber);
    app.add_option("--youngs", youngs, "Young's modulus in Pa")->check(CLI::PositiveNumber);
    app.add_option("--twist", twist_deg, "Total twist of the free end over the run, degrees");
    app.add_option("--max-outer", max_outer, "Outer (RNN-1) loops per step at most")
        ->check(CLI::Range(1, 1000000));
    app.add_option("--outer-tolerance", outer_tolerance,
                   "RNN-1 stops when the relative change of x falls below this")
        ->check(CLI::PositiveNumber);
    app.add_option("--plain-cap", plain_cap, "Most loops tried for plain Jacobi")
        ->check(CLI::Range(50, 1000000));
    app.add_option("--anderson", anderson, "Anderson depth of the outer loop (0 = off)")
        ->check(CLI::Range(0, 16));
    app.add_option("--tolerance", tolerance, "Allowed error of K = 18 Jacobi at 50 loops");
    app.add_option("--csv", csv, "Write the table to this CSV file");
  }
};

Config beam_deck(const Options& o, const std::string& method) {
  // Beam 0.5 x 0.1 x 0.1 m along x; x = 0 clamped, x = 0.5 turned about the beam axis by
  // twist_deg over the run; under gravity.
  const double omega = o.twist_deg * M_PI / 180.0 / (o.steps * o.dt);
  BeamDeck b;
  b.dt = o.dt;
  b.end_time = o.dt * o.steps;
  b.gravity = Vec3d{0, 0, -9.81};
  b.voxel_size = o.voxel;
  b.law = "stable_neo_hookean";
  b.target = "analytic";
  b.youngs_modulus = o.youngs;
  b.method = method;
  const std::string text = b.text()
                               .array("kinematic")
                               .set("lo", Vec3d{0.499, -1, -1})
                               .set("hi", Vec3d{1, 1, 1})
                               .set("center", Vec3d{0.5, 0.05, 0.05})
                               .set("angular_velocity", Vec3d{omega, 0, 0})
                               .str();
  return parse_deck(text, "<twisted beam " + method + ">", ".");
}

struct Run {
  std::vector<std::vector<double>> x;  // owned positions after each step (step 0: rest)
  double seconds = 0;
  double sweeps = 0, outer = 0;      // per step
  double res_mean = 0, res_max = 0;  // true residual after the loops
};

Run simulate(const Config& cfg, int steps) {
  log::set_quiet(true);  // the per-run banner would drown the table
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
  log::set_quiet(false);
  Run r;
  r.x.push_back(sim.owned_positions());
  const double t0 = MPI_Wtime();
  long sweeps = 0, outer = 0;
  for (int s = 0; s < steps; ++s) {
    const auto st = sim.dynamics().step(s * cfg.dt);
    sweeps += st.sweeps;
    outer += st.outer;
    r.res_mean += st.accuracy / steps;
    r.res_max = std::max(r.res_max, st.accuracy);
    if (cfg.solver.method == "newton" && !st.accurate)
      log::info("  newton step {}: residual {:.2e} above tolerance", s + 1, st.accuracy);
    r.x.push_back(sim.owned_positions());
  }
  r.seconds = MPI_Wtime() - t0;
  r.sweeps = double(sweeps) / steps;
  r.outer = double(outer) / steps;
  return r;
}

//! max over steps and owned nodes of |a - b| (per node), over all ranks.
double max_distance(const std::vector<std::vector<double>>& a,
                    const std::vector<std::vector<double>>& b, bool against_rest = false) {
  double m = 0;
  for (std::size_t s = 0; s < a.size(); ++s) {
    const auto& ref = against_rest ? b[0] : b[s];
    for (std::size_t n = 0; n + 2 < a[s].size(); n += 3)
      m = std::max(
          m, std::hypot(a[s][n] - ref[n], a[s][n + 1] - ref[n + 1], a[s][n + 2] - ref[n + 2]));
  }
  MPI_Allreduce(MPI_IN_PLACE, &m, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
  return m;
}

int run(const Options& o) {
  std::ofstream csv;
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  if (!o.csv.empty() && rank == 0) {  // one writer: the table is the same on every rank
    csv.open(o.csv);
    if (!csv) throw InputError(o.csv + ": cannot write the CSV file");
    csv << "series,relaxation,subspace_modes,loops,error,residual_mean,residual_max,"
           "sweeps_per_step,outer_per_step,seconds\n";
  }
  log::info(
      "twisted beam 0.5 x 0.1 x 0.1 m, Neo-Hookean, E = {:g} Pa, nu = 0.3, h = {} m, "
      "{} steps of {} s, twist {} deg",
      o.youngs, o.voxel, o.steps, o.dt, o.twist_deg);
  log::info(
      "loops = relaxation sweeps per global step (inner_tolerance = 0); outer loops to "
      "outer_tolerance {:g} (at most {}); no extra loops; anderson_depth = {}",
      o.outer_tolerance, o.max_outer, o.anderson);
  const Run ref = simulate(beam_deck(o, "newton"), o.steps);
  const double amp = max_distance(ref.x, ref.x, true);
  log::info("Newton reference: max displacement {:.4e} m, {:.1f} Newton iterations/step, {:.2f} s",
            amp, ref.outer, ref.seconds);
  log::info(
      "error = max_(steps, nodes) |x_E - x_N| / max displacement; residual = true "
      "implicit-Euler residual after the loops (mean / max over steps)");
  log::info("{:<10} {:>3} {:>5} {:>10} {:>10} {:>10} {:>11} {:>9} {:>8}", "relaxation", "K",
            "loops", "error", "res mean", "res max", "sweeps/step", "outer/step", "time [s]");
  auto measure = [&](const std::string& series, const std::string& relaxation, int K, int loops) {
    Config cfg = beam_deck(o, "elastogen");
    auto& s = cfg.solver;
    s.relaxation = relaxation;
    s.subspace_modes = K;
    s.max_sweeps = loops;
    s.inner_tolerance = 0;
    s.max_outer = o.max_outer;
    s.outer_tolerance = o.outer_tolerance;
    s.max_extra_outer = 0;
    s.anderson_depth = o.anderson;
    const Run r = simulate(cfg, o.steps);
    const double err = max_distance(r.x, ref.x) / amp;
    log::info("{:<10} {:>3} {:>5} {:>9.3f}% {:>10.2e} {:>10.2e} {:>11.0f} {:>9.1f} {:>8.2f}",
              relaxation, K, loops, 100 * err, r.res_mean, r.res_max, r.sweeps, r.outer, r.seconds);
    if (csv)
      csv << series << ',' << relaxation << ',' << K << ',' << loops << ',' << err << ','
          << r.res_mean << ',' << r.res_max << ',' << r.sweeps << ',' << r.outer << ',' << r.seconds
          << '\n';
    return err;
  };
  double target_err = 0;
  for (const char* relaxation : {"jacobi", "chebyshev"})
    for (int K : {18, 0})
      for (int loops : {1, 3, 5, 20, 50}) {
        const double err = measure("loops", relaxation, K, loops);
        if (std::string(relaxation) == "jacobi" && K == 18 && loops == 50) target_err = err;
      }
  log::info(
      "plain Jacobi (K = 0, damped Jacobi), doubling the loops until the error of K = 18 "
      "Jacobi at 50 loops ({:.3f}%) is reached, at most {} loops:",
      100 * target_err, o.plain_cap);
  int reached = 0;
  for (int loops = 50; loops <= o.plain_cap;
       loops = loops * 2 > o.plain_cap && loops < o.plain_cap ? o.plain_cap : loops * 2) {
    if (measure("plain_jacobi", "jacobi", 0, loops) <= target_err) {
      reached = loops;
      break;
    }
    if (loops == o.plain_cap) break;
  }
  if (reached)
    log::info("plain Jacobi needs {} loops (sweeps per global step) for that error", reached);
  else
    log::info("plain Jacobi did not reach that error within {} loops", o.plain_cap);
  const bool ok = target_err <= o.tolerance;
  log::info("K = 18 damped Jacobi, 50 loops: error {:.3f}% (target <= {:.1f}%){}", 100 * target_err,
            100 * o.tolerance, ok ? "" : "  FAIL");
  return ok ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  return driver::main_with_options<Options>(
      argc, argv, "ElastoGen vs Newton reference: error vs relaxation loops, twisted beam", run);
}
