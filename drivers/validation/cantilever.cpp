// validate_cantilever — ElastoGen against the Newton reference on a cantilever bending
// under gravity (seed paper Fig. 4b): materials {corotated, Neo-Hookean, StVK} x Poisson
// ratio {0.20, 0.30, 0.45} at a fixed Young's modulus.
//
// Sample runs:
//   mpirun -np 2 build/drivers/validate_cantilever
//   build/drivers/validate_cantilever --steps 20 --csv tip.csv
//   python3 drivers/validation/plot_cantilever.py tip.csv cantilever.png
//
// Description:
//   1. Build the beam deck (clamped at x = 0, gravity along -z) for each case.
//   2. Run ElastoGen (analytic target: p = F - P(F)/k, default solver settings) and the
//      Newton reference (PETSc SNES on the same voxels and energy) step by step.
//   3. Record the tip's mean vertical position; report max |z_E - z_N| / max |z_N - z_0|.
//   4. Exit 1 if any case exceeds the tolerance (default 2 %), so the driver is also a check.
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "core/Deck.hpp"
#include "core/Error.hpp"
#include "core/Log.hpp"
#include "elastogen/Simulation.hpp"
#include "validation/DriverCommon.hpp"

using namespace gen4d;

namespace {

struct Options {
  int steps = 100;
  double voxel = 0.025, youngs = 1e6, tolerance = 0.02;
  std::string csv;
};

Config beam_deck(const Options& o, const std::string& model, double nu, const std::string& method) {
  const std::string text = fmt::format(R"(
[simulation]
dt = 0.01
end_time = {}
[domain]
voxel_size = {}
padding = 0
[[geometry]]
type = "box"
lo = [0.0, 0.0, 0.0]
hi = [0.5, 0.1, 0.1]
[material]
model = "{}"
target = "analytic"
youngs_modulus = {}
poisson_ratio = {}
density = 1000.0
[solver]
method = "{}"
[[fixed]]
lo = [-1.0, -1.0, -1.0]
hi = [0.001, 1.0, 1.0]
)",
                                       0.01 * o.steps, o.voxel, model, o.youngs, nu, method);
  return parse_deck(text, "<cantilever " + model + ">", ".");
}

double tip_z(elastogen::Simulation& sim) {
  return driver::end_face_mean(sim, 2);
}

std::vector<double> trajectory(const Config& cfg, int steps, double& seconds, long& loops) {
  log::set_quiet(true);  // the per-run banner would drown the table
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
  log::set_quiet(false);
  std::vector<double> z{tip_z(sim)};
  const double t0 = MPI_Wtime();
  loops = 0;
  for (int s = 0; s < steps; ++s) {
    const auto st = sim.dynamics().step(s * cfg.dt);
    loops += st.outer;
    if (!st.accurate)
      log::info("  {} step {}: residual {:.2e} above tolerance", cfg.solver.method, s + 1,
                st.accuracy);
    z.push_back(tip_z(sim));
  }
  seconds = MPI_Wtime() - t0;
  return z;
}

int run(const Options& o) {
  std::ofstream csv;
  if (!o.csv.empty()) {
    csv.open(o.csv);
    if (!csv) throw InputError(o.csv + ": cannot write the CSV file");
    csv << "model,nu,step,time,z_elastogen,z_newton\n";
  }
  log::info("cantilever 0.5 x 0.1 x 0.1 m, h = {} m, E = {:g} Pa, {} steps of 0.01 s", o.voxel,
            o.youngs, o.steps);
  log::info("{:<12} {:>5} {:>12} {:>12} {:>9} {:>10} {:>10}", "model", "nu", "max tip [m]",
            "max err [m]", "err/max", "t_E [s]", "t_N [s]");
  int failures = 0;
  for (const char* model : {"corotated", "neo_hookean", "stvk"})
    for (double nu : {0.20, 0.30, 0.45}) {
      double te = 0, tn = 0;
      long le = 0, ln = 0;
      const auto ze = trajectory(beam_deck(o, model, nu, "elastogen"), o.steps, te, le);
      const auto zn = trajectory(beam_deck(o, model, nu, "newton"), o.steps, tn, ln);
      double err = 0, amp = 0;
      for (std::size_t s = 0; s < ze.size(); ++s) {
        err = std::max(err, std::fabs(ze[s] - zn[s]));
        amp = std::max(amp, std::fabs(zn[s] - zn[0]));
        if (csv)
          csv << model << ',' << nu << ',' << s << ',' << 0.01 * s << ',' << ze[s] << ',' << zn[s]
              << '\n';
      }
      const double rel = err / amp;
      failures += rel > o.tolerance;
      log::info("{:<12} {:>5.2f} {:>12.4e} {:>12.3e} {:>8.3f}% {:>10.2f} {:>10.2f}{}", model, nu,
                amp, err, 100 * rel, te, tn, rel > o.tolerance ? "  FAIL" : "");
    }
  log::info("{} of 9 cases within {:.1f}% of the Newton reference", 9 - failures,
            100 * o.tolerance);
  return failures == 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  return driver::main_with(
      argc, argv, "ElastoGen vs Newton reference: cantilever under gravity, 3 materials x 3 nu",
      [&](CLI::App& app) {
        app.add_option("--steps", o.steps, "Time steps of 0.01 s")->check(CLI::Range(1, 100000));
        app.add_option("--voxel", o.voxel, "Voxel size in metres")->check(CLI::PositiveNumber);
        app.add_option("--youngs", o.youngs, "Young's modulus in Pa")->check(CLI::PositiveNumber);
        app.add_option("--tolerance", o.tolerance, "Allowed max error / max tip displacement");
        app.add_option("--csv", o.csv, "Write tip trajectories to this CSV file");
      },
      [&] { return run(o); });
}
