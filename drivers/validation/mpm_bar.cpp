// Elastic validation of the MPM solver: the first axial mode of a free-free bar and momentum
// conservation.
//
// A bar of length L (axis x) and square section h x h, density rho, Young's modulus E, is
// given the velocity of its first free-free axial mode, v_x = v0 cos(pi x / L), plus a
// uniform drift u0 along (1, 0.5, 0.25), without gravity or any boundary contact. The mode
// oscillates at f = c / (2 L), c = sqrt(E / rho) (slender bar; Rayleigh's lateral-inertia
// correction is (nu pi r_g / L)^2 / 2 ~ 1e-4 here). The driver records the momentum of the
// left half relative to the drift, finds its zero crossings, and compares the measured
// frequency with f (target 3 %). It also reports the largest drift of the total momentum
// relative to its initial value over the run (target: round-off, 1e-10).
#include <cmath>
#include <cstdio>
#include <vector>

#include "validation/DriverCommon.hpp"
#include "validation/MpmCommon.hpp"

namespace gen4d {
namespace {

int run(int cells, int periods, const std::string& csv) {
  MPI_Comm comm = MPI_COMM_WORLD;
  const double L = 1.0, h = 0.1, rho = 1000, E = 1e7, nu = 0.3, v0 = 0.05;
  const Vec3d drift{0.2, 0.1, 0.05};
  const double dx = L / cells;
  const int pad = 6;
  mpm::GridSpec grid;
  grid.dx = dx;
  const long hcells = std::lround(h / dx);
  // Room for the drift: 0.2 m/s over `periods` periods of 20 ms, under 3 cells.
  grid.cells = {cells + 2 * pad + 4, hcells + 2 * pad + 4, hcells + 2 * pad + 4};
  grid.lo = {-pad * dx, -(pad + 2) * dx, -(pad + 2) * dx};
  auto material = driver::mpm_material(
      "neo_hookean", {{"youngs_modulus", E}, {"poisson_ratio", nu}, {"density", rho}});
  mpm::SolverOptions opt;
  opt.gravity = {0, 0, 0};
  opt.max_dt = 1e-3;
  const geometry::Box bar(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(L, h, h));
  auto solver = driver::mpm_solver(comm, grid, material, opt, {}, bar, 2);
  mpm::Particles& p = solver->particles();
  for (std::size_t i = 0; i < p.size(); ++i) {
    p.v[3 * i + 0] = v0 * std::cos(M_PI * p.x[3 * i] / L) + drift[0];
    p.v[3 * i + 1] = drift[1];
    p.v[3 * i + 2] = drift[2];
  }
  const auto P0 = solver->total_momentum();
  const double c = std::sqrt(E / rho);
  const double f_exact = c / (2 * L);
  const double T = 1 / f_exact;
  const double sample = T / 200;
  // Momentum of the left half relative to the drift; the centre moves with the drift.
  auto left_momentum = [&](double t) {
    parallel::ExactSum s;
    const double centre = L / 2 + drift[0] * t;
    for (std::size_t i = 0; i < p.size(); ++i)
      if (p.x[3 * i] < centre) s.add(p.mass[i] * (p.v[3 * i] - drift[0]));
    double out = 0;
    parallel::Reducer(comm).sum(&s, &out, 1);
    return out;
  };
  double t = 0, max_drift = 0;
  std::vector<double> ts, ms;
  long substeps = 0;
  const int samples = static_cast<int>(std::lround(periods * T / sample));
  for (int k = 0; k <= samples; ++k) {
    if (k > 0) substeps += driver::advance(*solver, t, k * sample);
    const auto P = solver->total_momentum();
    double d = 0, n0 = 0;
    for (int a = 0; a < 3; ++a) {
      d += (P[a] - P0[a]) * (P[a] - P0[a]);
      n0 += P0[a] * P0[a];
    }
    max_drift = std::max(max_drift, std::sqrt(d / n0));
    ts.push_back(t);
    ms.push_back(left_momentum(t));
  }
  // Zero crossings (linear interpolation) of the left-half momentum.
  std::vector<double> zeros;
  for (std::size_t k = 1; k < ms.size(); ++k)
    if ((ms[k - 1] > 0) != (ms[k] > 0))
      zeros.push_back(ts[k - 1] + (ts[k] - ts[k - 1]) * ms[k - 1] / (ms[k - 1] - ms[k]));
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  if (zeros.size() < 3) {
    if (rank == 0) std::printf("FAIL: fewer than 3 zero crossings\n");
    return 1;
  }
  const double half_periods = static_cast<double>(zeros.size() - 1);
  const double f_measured = half_periods / (2 * (zeros.back() - zeros.front()));
  const double err = std::abs(f_measured - f_exact) / f_exact;
  const bool ok = err <= 0.03 && max_drift <= 1e-10;
  const long long count = solver->count();
  if (rank == 0) {
    std::printf(
        "MPM elastic bar: L = %g m, h = %g m, E = %g Pa, rho = %g kg/m^3, %d cells along L, "
        "%lld particles, %ld substeps\n",
        L, h, E, rho, cells, count, substeps);
    std::printf(
        "  first axial mode: measured %.4f Hz, c/(2L) = %.4f Hz, error %.2f %% (target 3 %%)\n",
        f_measured, f_exact, 100 * err);
    std::printf("  total momentum drift: %.3e relative (target 1e-10)\n", max_drift);
    std::printf("%s\n", ok ? "PASS" : "FAIL");
    if (!csv.empty()) {
      FILE* f = std::fopen(csv.c_str(), "w");
      if (!f) throw RuntimeError(csv + ": cannot write");
      std::fprintf(f, "t,left_half_momentum\n");
      for (std::size_t k = 0; k < ts.size(); ++k) std::fprintf(f, "%.9g,%.9g\n", ts[k], ms[k]);
      std::fclose(f);
    }
  }
  return ok ? 0 : 1;
}

}  // namespace
}  // namespace gen4d

int main(int argc, char** argv) {
  int cells = 40, periods = 3;
  std::string csv;
  return gen4d::driver::main_with(
      argc, argv, "MPM elastic bar: axial frequency vs c/(2L) and momentum conservation",
      [&](CLI::App& app) {
        app.add_option("--cells", cells, "Cells along the bar")->check(CLI::Range(8, 400));
        app.add_option("--periods", periods, "Periods simulated")->check(CLI::Range(1, 50));
        app.add_option("--csv", csv, "Write t, left-half momentum");
      },
      [&] { return gen4d::run(cells, periods, csv); });
}
