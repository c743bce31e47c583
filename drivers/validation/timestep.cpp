// validate_timestep — large time steps: a soft beam sagging under gravity with ElastoGen at
// dt = 1/100 s (the seed claims stability at 5e-3 s where explicit methods need < 6e-5 s).
//
// Sample runs:
//   mpirun -np 2 build/drivers/validate_timestep
//   build/drivers/validate_timestep --end-time 0.3 --csv timestep.csv
//   python3 drivers/validation/plot_timestep.py timestep.csv timestep.png
//
// Description:
//   Neo-Hookean beam 0.5 x 0.1 x 0.1 m, h = 1/80 m (40 x 8 x 8 voxels, 9963 DoFs),
//   E = 1e6 Pa, nu = 0.4, rho = 1000 kg/m^3, clamped at x = 0, released from rest under
//   gravity: its tip drops ~30 % of the beam length and swings (large rotation, nonlinear).
//   1. Explicit limit: the P-wave speed c = sqrt((lambda + 2 mu) / rho) gives the usual CFL
//      bound dt_explicit ~ h / (c sqrt(3)) for trilinear hexahedra with lumped mass.
//   2. Accuracy: ElastoGen (analytic target, default solver settings) vs the Newton
//      reference with the same implicit-Euler step: max |tip_E - tip_N| over the run divided
//      by the reference's max tip displacement. Target <= 1 %.
//   3. Stability: ElastoGen at dt in {1/200, 1/100, 1/50, 1/20} s: every state finite and the
//      total energy (kinetic + elastic + gravity) never rises between steps by more than
//      1e-6 of its scale (implicit Euler dissipates; growth would mean instability).
//   4. Time-discretisation error (reported, no target): the Newton reference at dt / 5 shows
//      what implicit Euler's numerical damping costs at dt = 1/100 s.
//   Exit 1 if 2 or 3 fails.
#include <cmath>
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
  double end_time = 0.5, dt = 0.01, voxel = 0.0125, youngs = 1e6, nu = 0.4;
  std::string model = "neo_hookean";
  double tolerance = 0.01;
  bool skip_fine = false;
  std::string csv;

  //! Declares the command-line options.
  void add(CLI::App& app) {
    app.add_option("--end-time", end_time, "Simulated seconds")->check(CLI::PositiveNumber);
    app.add_option("--dt", dt, "Time step in seconds")->check(CLI::PositiveNumber);
    app.add_option("--voxel", voxel, "Voxel size in metres")->check(CLI::PositiveNumber);
    app.add_option("--youngs", youngs, "Young's modulus in Pa")->check(CLI::PositiveNumber);
    app.add_option("--nu", nu, "Poisson ratio")->check(CLI::Range(0.0, 0.49));
    app.add_option("--model", model, "Material law")
        ->check(CLI::IsMember({"corotated", "neo_hookean", "stvk"}));
    app.add_option("--tolerance", tolerance, "Allowed tip error vs Newton");
    app.add_flag("--skip-fine", skip_fine, "Skip the dt/5 reference run");
    app.add_option("--csv", csv, "Write tip trajectories to this CSV file");
  }
};

Config beam_deck(const Options& o, double dt, const std::string& method) {
  BeamDeck b;
  b.dt = dt;
  b.end_time = o.end_time;
  b.voxel_size = o.voxel;
  b.law = o.model;
  b.target = "analytic";
  b.youngs_modulus = o.youngs;
  b.poisson_ratio = o.nu;
  b.method = method;
  return parse_deck(b.text().str(), "<soft beam>", ".");
}

struct Run {
  std::vector<double> t, tip;  //!< tip = mean z of the free end's nodes
  double seconds = 0, max_energy_rise = 0, energy_scale = 0;
  long loops = 0, inaccurate = 0;
  bool finite = true;
};

Run simulate(const Options& o, double dt, const std::string& method) {
  const Config cfg = beam_deck(o, dt, method);
  log::set_quiet(true);
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
  log::set_quiet(false);
  Run r;
  r.t.push_back(0);
  r.tip.push_back(driver::end_face_mean(sim, 2));
  const auto e0 = sim.dynamics().energy();
  double e_prev = e0.total();
  const long steps = std::lround(o.end_time / dt);
  const double t0 = MPI_Wtime();
  for (long s = 0; s < steps; ++s) {
    const auto st = sim.dynamics().step(s * dt);
    r.loops += st.outer;
    r.inaccurate += !st.accurate;
    const auto e = sim.dynamics().energy();
    r.energy_scale = std::max(r.energy_scale,
                              e.kinetic + std::fabs(e.elastic) + std::fabs(e.gravity - e0.gravity));
    r.max_energy_rise = std::max(r.max_energy_rise, e.total() - e_prev);
    e_prev = e.total();
    r.t.push_back((s + 1) * dt);
    r.tip.push_back(driver::end_face_mean(sim, 2));
    if (!std::isfinite(r.tip.back()) || !std::isfinite(e.total())) {
      r.finite = false;
      break;
    }
  }
  r.seconds = MPI_Wtime() - t0;
  return r;
}

//! max_t |a(t) - b(t)| / max_t |b(t) - b(0)|, b sampled on a grid `stride` times finer.
double relative_error(const Run& a, const Run& b, int stride, double* amp_out = nullptr) {
  double err = 0, amp = 0;
  for (std::size_t s = 0; s < b.tip.size(); ++s)
    amp = std::max(amp, std::fabs(b.tip[s] - b.tip[0]));
  for (std::size_t s = 0; s < a.tip.size() && s * stride < b.tip.size(); ++s)
    err = std::max(err, std::fabs(a.tip[s] - b.tip[s * stride]));
  if (amp_out) *amp_out = amp;
  return err / amp;
}

int run(const Options& o) {
  const double E = o.youngs, nu = o.nu, rho = 1000.0;
  const double lambda = E * nu / ((1 + nu) * (1 - 2 * nu)), mu = E / (2 * (1 + nu));
  const double c = std::sqrt((lambda + 2 * mu) / rho);
  const double dt_explicit = o.voxel / (c * std::sqrt(3.0));
  log::info("soft beam 0.5 x 0.1 x 0.1 m, h = {} m, {} E = {:g} Pa nu = {}, {} s under gravity",
            o.voxel, o.model, E, nu, o.end_time);
  log::info(
      "1. explicit CFL estimate: c_p = {:.1f} m/s, dt_explicit ~ h / (c sqrt 3) = {:.2e} s; "
      "dt = {} s is {:.0f}x larger",
      c, dt_explicit, o.dt, o.dt / dt_explicit);
  int failures = 0;

  const Run e = simulate(o, o.dt, "elastogen");
  const Run n = simulate(o, o.dt, "newton");
  double amp = 0;
  const double err = e.finite && n.finite ? relative_error(e, n, 1, &amp) : INFINITY;
  log::info(
      "2. ElastoGen vs Newton at dt = {} s: max tip difference {:.3f} % of the max tip "
      "displacement ({:.4f} m); {:.2f} loops/step, {} steps above the residual tolerance; "
      "time {:.2f} s vs {:.2f} s",
      o.dt, 100 * err, amp, double(e.loops) / (e.t.size() - 1), e.inaccurate, e.seconds, n.seconds);
  failures += !(err <= o.tolerance);

  log::info("3. stability of ElastoGen:");
  log::info("{:>10} {:>9} {:>8} {:>16} {:>12} {:>12}", "dt [s]", "x explicit", "finite",
            "max energy rise", "min tip [m]", "loops/step");
  for (double dt : {o.dt / 2, o.dt, 2 * o.dt, 5 * o.dt}) {
    const Run r = dt == o.dt ? e : simulate(o, dt, "elastogen");
    double lo = 0;
    for (double z : r.tip) lo = std::min(lo, z - r.tip[0]);
    const double rise = r.max_energy_rise / r.energy_scale;
    const bool ok = r.finite && rise <= 1e-6;
    failures += !ok;
    log::info("{:>10.4f} {:>9.0f} {:>8} {:>16.2e} {:>12.4f} {:>12.2f}{}", dt, dt / dt_explicit,
              r.finite ? "yes" : "NO", rise, lo, double(r.loops) / (r.t.size() - 1),
              ok ? "" : "  FAIL");
  }

  if (!o.skip_fine) {
    const Run f = simulate(o, o.dt / 5, "newton");
    const double ei = relative_error(n, f, 5);
    log::info(
        "4. implicit Euler at dt = {} s vs dt = {} s (Newton both): max tip difference "
        "{:.1f} % of the max tip displacement (numerical damping of the integrator, the "
        "same for any solver of this step)",
        o.dt, o.dt / 5, 100 * ei);
    if (!o.csv.empty()) {
      std::ofstream csv(o.csv);
      if (!csv) throw InputError(o.csv + ": cannot write the CSV file");
      csv << "t,tip_elastogen,tip_newton,tip_newton_fine\n";
      for (std::size_t s = 0; s < e.tip.size() && 5 * s < f.tip.size(); ++s)
        csv << e.t[s] << ',' << e.tip[s] << ',' << n.tip[s] << ',' << f.tip[5 * s] << '\n';
    }
  }
  log::info("{}", failures ? "target missed" : "stable and within tolerance of the reference");
  return failures ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  return driver::main_with_options<Options>(
      argc, argv, "Large time steps: soft beam under gravity, ElastoGen vs Newton reference", run);
}
