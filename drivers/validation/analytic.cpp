// validate_analytic — ElastoGen against closed-form beam theory, with a grid-convergence
// table: (1) static tip deflection of a cantilever under a small end load vs Euler-Bernoulli
// (and Timoshenko), (2) first bending frequency of the clamped beam vs Euler-Bernoulli.
//
// Sample runs:
//   mpirun -np 2 build/drivers/validate_analytic       # static H/2..H/8, frequency H/2, H/4
//   build/drivers/validate_analytic --static-levels 2,4 --frequency-levels 2,4,8 --csv a.csv
//   python3 drivers/validation/plot_analytic.py analytic.csv analytic.png
//
// Description:
//   Beam 0.4 x 0.04 x 0.04 m (L/H = 10), E = 1e6 Pa, nu = 0 (no anticlastic clamp
//   stiffening), rho = 1000 kg/m^3, clamped at x = 0, h = H/n for each level n.
//   1. Static: one implicit-Euler step of dt = 1e4 s from rest (inertia negligible) under
//      an end load of 0.01 N (deflection ~0.3 % of L, the linear regime). Solved by ElastoGen
//      (analytic target, CG relaxation; damped Jacobi needs O(condition) sweeps without a mass
//      term) and by the Newton reference on the same voxels, which must agree.
//   2. Dynamic: the tip is pushed for 0.05 s and released; dt = T/100; the period is read
//      from upward zero crossings of the mean end-face displacement over ~2 periods.
//   From three successive levels (ratio 2) the observed order p = log2((v1 - v0) / (v2 - v1))
//   and the Richardson estimate of the h -> 0 limit v2 + (v2 - v1) / (2^p - 1) are printed. Beam
//   theory is not the continuum answer: Timoshenko shear adds 0.6 (H/L)^2 = +0.6 % to the static
//   deflection. Exit 1 if the finest level of either study misses the 3 % target.
#include <cmath>
#include <fstream>
#include <sstream>
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

constexpr double kL = 0.4, kH = 0.04, kE = 1e6, kRho = 1000, kLoad = 0.01;

struct Options {
  std::vector<int> static_levels{2, 4, 8}, frequency_levels{2, 4};
  double tolerance = 0.03;
  bool skip_static = false, skip_frequency = false;
  std::string csv;

  //! Declares the command-line options.
  void add(CLI::App& app) {
    app.add_option("--static-levels", static_levels,
                   "Voxels through the thickness for the static study, coarse to fine")
        ->delimiter(',')
        ->check(CLI::Range(1, 64));
    app.add_option("--frequency-levels", frequency_levels,
                   "Voxels through the thickness for the frequency study")
        ->delimiter(',')
        ->check(CLI::Range(1, 64));
    app.add_option("--tolerance", tolerance, "Allowed |error| at the finest level");
    app.add_flag("--skip-static", skip_static, "Skip the static deflection study");
    app.add_flag("--skip-frequency", skip_frequency, "Skip the frequency study");
    app.add_option("--csv", csv, "Write the table to this CSV file");
  }
};

Config beam_deck(int n, double dt, double end_time, double load_end, const std::string& method,
                 const std::string& relaxation, const DeckText& extra) {
  const double h = kH / n;
  BeamDeck b;
  b.dt = dt;
  b.end_time = end_time;
  b.gravity = Vec3d{0, 0, 0};
  b.voxel_size = h;
  b.hi = {kL, kH, kH};
  b.target = "analytic";
  b.youngs_modulus = kE;
  b.poisson_ratio = 0;
  b.density = kRho;
  b.method = method;
  b.solver.set("relaxation", relaxation).append(extra);
  b.fixed_hi = {0.1 * h, 1, 1};
  const std::string text = b.text()
                               .array("force")
                               .set("lo", Vec3d{kL - 0.1 * h, -1, -1})
                               .set("hi", Vec3d{1, 1, 1})
                               .set("force", Vec3d{0, 0, -kLoad})
                               .set("end", load_end)
                               .str();
  return parse_deck(text, fmt::format("<beam H/{}>", n), ".");
}

struct StaticResult {
  double deflection = 0, seconds = 0, residual = 0;
  int loops = 0;
  long sweeps = 0;
};

StaticResult static_deflection(int n, const std::string& method) {
  DeckText extra;
  extra.set("max_sweeps", 50000)
      .set("inner_tolerance", 1e-4)
      .set("max_outer", 50000)
      .set("max_extra_outer", 50000)
      .set("outer_tolerance", 1e-6)
      .set("accuracy_tolerance", 1e-3);
  const Config cfg = beam_deck(n, 1e4, 1e4, 1e300, method, "cg", extra);
  log::set_quiet(true);
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
  log::set_quiet(false);
  const double z0 = driver::end_face_mean(sim, 2);
  const double t0 = MPI_Wtime();
  const auto st = sim.dynamics().step(0.0);
  StaticResult r;
  r.seconds = MPI_Wtime() - t0;
  r.deflection = z0 - driver::end_face_mean(sim, 2);
  r.loops = st.outer;
  r.sweeps = st.sweeps;
  r.residual = st.accuracy;
  if (!st.accurate)
    log::info("  warning: {} at H/{} stopped at residual {:.1e}", method, n, st.accuracy);
  return r;
}

struct FrequencyResult {
  double frequency = 0, seconds = 0;
  int periods = 0;
  long steps = 0, loops = 0;
};

FrequencyResult bending_frequency(int n, double f_eb) {
  const double dt = 1.0 / f_eb / 100.0, push = 0.05;
  const long steps = static_cast<long>(std::ceil((2.3 / f_eb + push) / dt));
  DeckText extra;
  extra.set("accuracy_tolerance", 1e-4).set("max_extra_outer", 1000);
  const Config cfg = beam_deck(n, dt, steps * dt, push, "elastogen", "jacobi", extra);
  log::set_quiet(true);
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
  log::set_quiet(false);
  const double z0 = driver::end_face_mean(sim, 2);
  FrequencyResult r;
  std::vector<double> t{0.0}, z{0.0};
  const double t0 = MPI_Wtime();
  for (long s = 0; s < steps; ++s) {
    const auto st = sim.dynamics().step(s * dt);
    r.loops += st.outer;
    if (!st.accurate)
      throw RuntimeError(
          fmt::format("H/{}: step {} residual {:.1e} above tolerance", n, s + 1, st.accuracy));
    t.push_back((s + 1) * dt);
    z.push_back(driver::end_face_mean(sim, 2) - z0);
  }
  r.seconds = MPI_Wtime() - t0;
  r.steps = steps;
  std::vector<double> up;  // upward zero crossings after the release
  for (std::size_t i = 1; i < z.size(); ++i)
    if (t[i - 1] > push && z[i - 1] < 0 && z[i] >= 0)
      up.push_back(t[i - 1] + (t[i] - t[i - 1]) * (-z[i - 1]) / (z[i] - z[i - 1]));
  if (up.size() < 2) throw RuntimeError(fmt::format("H/{}: fewer than two crossings", n));
  r.periods = static_cast<int>(up.size()) - 1;
  r.frequency = r.periods / (up.back() - up.front());
  return r;
}

//! Observed order of convergence from the values at three successive levels (ratio r),
//! or NaN when the differences do not shrink monotonically.
double observed_order(double v0, double v1, double v2, double r) {
  const double q = (v1 - v0) / (v2 - v1);
  return q > 1.0 ? std::log(q) / std::log(r) : NAN;
}

//! Order column and Richardson line of a grid study of values `v` at `levels`.
std::string order_at(const std::vector<double>& v, const std::vector<int>& levels) {
  const std::size_t l = v.size() - 1;
  if (l < 2 || levels[l] != 2 * levels[l - 1] || levels[l - 1] != 2 * levels[l - 2]) return "-";
  return fmt::format("{:.2f}", observed_order(v[l - 2], v[l - 1], v[l], 2.0));
}

void richardson(const std::vector<double>& v, const std::vector<int>& levels,
                const std::vector<std::pair<const char*, double>>& analytic, const char* unit) {
  const std::size_t l = v.size() - 1;
  if (l < 2 || levels[l] != 2 * levels[l - 1] || levels[l - 1] != 2 * levels[l - 2]) return;
  const double p = observed_order(v[l - 2], v[l - 1], v[l], 2.0);
  if (!std::isfinite(p)) {
    log::info("  no Richardson estimate: the differences do not shrink monotonically");
    return;
  }
  const double lim = v[l] + (v[l] - v[l - 1]) / (std::pow(2.0, p) - 1);
  std::string vs;
  for (const auto& [name, a] : analytic)
    vs += fmt::format(", {:+.2f} % vs {}", 100 * (lim - a) / a, name);
  log::info("  Richardson limit (p = {:.2f}): {:.5e} {}{}", p, lim, unit, vs);
}

int run(const Options& o) {
  std::ofstream csv;
  if (!o.csv.empty()) {
    csv.open(o.csv);
    if (!csv) throw InputError(o.csv + ": cannot write the CSV file");
    csv << "check,n,h,value,analytic,error\n";
  }
  const double I = kH * kH * kH * kH / 12.0, A = kH * kH;
  const double d_eb = kLoad * kL * kL * kL / (3 * kE * I);
  const double d_timo = d_eb + kLoad * kL / (5.0 / 6.0 * kE / 2.0 * A);
  const double f_eb =
      1.8751 * 1.8751 / (2 * M_PI) * std::sqrt(kE * I / (kRho * A * std::pow(kL, 4)));
  int failures = 0;
  log::info("beam {} x {} x {} m, E = {:g} Pa, nu = 0, rho = {:g}; levels h = H/n", kL, kH, kH, kE,
            kRho);
  if (!o.skip_static) {
    log::info("");
    log::info(
        "1. static tip deflection, end load {} N: Euler-Bernoulli {:.5e} m, Timoshenko "
        "{:.5e} m",
        kLoad, d_eb, d_timo);
    log::info("{:>4} {:>8} {:>8} {:>13} {:>9} {:>8} {:>11} {:>9} {:>13} {:>9}", "n", "h [m]",
              "DoFs", "ElastoGen [m]", "err EB", "order", "loops", "t [s]", "Newton [m]", "t [s]");
    std::vector<double> errs, defl;
    for (std::size_t l = 0; l < o.static_levels.size(); ++l) {
      const int n = o.static_levels[l];
      const auto e = static_deflection(n, "elastogen");
      const auto nw = static_deflection(n, "newton");
      const double err = (e.deflection - d_eb) / d_eb;
      const long dofs = 3L * (10 * n + 1) * (n + 1) * (n + 1);
      defl.push_back(e.deflection);
      const std::string ord = order_at(defl, o.static_levels);
      log::info("{:>4} {:>8.4f} {:>8} {:>13.6e} {:>8.2f}% {:>8} {:>11} {:>9.2f} {:>13.6e} {:>9.2f}",
                n, kH / n, dofs, e.deflection, 100 * err, ord, e.loops, e.seconds, nw.deflection,
                nw.seconds);
      if (std::fabs(e.deflection - nw.deflection) > 1e-3 * d_eb)
        log::info("  note: ElastoGen and Newton differ by {:.2e} m", e.deflection - nw.deflection);
      if (csv)
        csv << "static," << n << ',' << kH / n << ',' << e.deflection << ',' << d_eb << ',' << err
            << '\n';
      errs.push_back(err);
    }
    failures += std::fabs(errs.back()) > o.tolerance;
    richardson(defl, o.static_levels, {{"Euler-Bernoulli", d_eb}, {"Timoshenko", d_timo}}, "m");
  }
  if (!o.skip_frequency) {
    log::info("");
    log::info("2. first bending frequency, dt = T/100: Euler-Bernoulli {:.5f} Hz", f_eb);
    log::info("{:>4} {:>8} {:>8} {:>10} {:>9} {:>8} {:>8} {:>10} {:>9}", "n", "h [m]", "DoFs",
              "f [Hz]", "err EB", "order", "periods", "loops", "t [s]");
    std::vector<double> errs, freq;
    for (std::size_t l = 0; l < o.frequency_levels.size(); ++l) {
      const int n = o.frequency_levels[l];
      const auto f = bending_frequency(n, f_eb);
      const double err = (f.frequency - f_eb) / f_eb;
      const long dofs = 3L * (10 * n + 1) * (n + 1) * (n + 1);
      freq.push_back(f.frequency);
      const std::string ord = order_at(freq, o.frequency_levels);
      log::info("{:>4} {:>8.4f} {:>8} {:>10.5f} {:>8.2f}% {:>8} {:>8} {:>10} {:>9.2f}", n, kH / n,
                dofs, f.frequency, 100 * err, ord, f.periods, f.loops, f.seconds);
      if (csv)
        csv << "frequency," << n << ',' << kH / n << ',' << f.frequency << ',' << f_eb << ',' << err
            << '\n';
      errs.push_back(err);
      if (l + 1 == o.frequency_levels.size()) failures += std::fabs(err) > o.tolerance;
    }
    richardson(freq, o.frequency_levels, {{"Euler-Bernoulli", f_eb}}, "Hz");
  }
  log::info("");
  log::info("finest levels: {}",
            failures ? "target missed" : fmt::format("within {:.0f} %", 100 * o.tolerance));
  return failures ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  return driver::main_with_options<Options>(
      argc, argv, "ElastoGen vs beam theory: static deflection and bending frequency, grid study",
      run);
}
