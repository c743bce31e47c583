// MPM throughput on this machine, printed as JSON, against the STREAM triad measured in the
// same run:
//   1. an elastic block (fixed corotated) and a sand block (Drucker-Prager) of about
//      --particles particles (8 per cell) dropped onto a floor, timed over --substeps substeps
//      after two warm-up substeps;
//   2. particle-substeps per second (total and per rank), a per-phase breakdown (max over
//      ranks: material, P2G, halo, grid, G2P, guard, migration), and the bytes a
//      particle-substep moves in the model below, as a fraction of STREAM.
// Bytes per particle-substep (the particle arrays each phase streams; the 3x3x3 grid
// neighbourhood stays in cache): material reads F, state and writes F, state, tau
// (9+4+9+4+9 doubles = 280 B); P2G reads x, v, C, tau, mass, vol0, flag (3+3+9+9+1+1 doubles
// + 1 B = 209 B); G2P reads x, flag, F and writes v, C, x, F (3+9+3+9+3+9 doubles + 1 B =
// 289 B); the guard reads x, v, F (15 doubles = 120 B); total 898 B. Grid passes add 112 B per
// ghosted node (mass, momentum, velocity written and read) and are reported separately.
// Strong scaling: run at 1 and 2 ranks (jobs/scaling/mpm-scaling.sh prints the speed-up).
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "bench/Stream.hpp"
#include "core/Device.hpp"
#include "core/ParallelFor.hpp"
#include "validation/DriverCommon.hpp"
#include "validation/MpmCommon.hpp"

namespace gen4d {
namespace {

constexpr double kParticleBytes = 898.0;
const char* kPhases[] = {"material", "p2g", "halo", "grid", "g2p", "guard", "migration"};

std::string run_case(const char* name, const std::string& model, long target, int substeps,
                     double stream, int size, bool device) {
  MPI_Comm comm = MPI_COMM_WORLD;
  const int n = std::max(4, static_cast<int>(std::lround(std::cbrt(target / 8.0))));
  const double dx = 1.0 / n;
  mpm::GridSpec g;
  g.dx = dx;
  const int pad = 6;
  g.lo = {-pad * dx, -pad * dx, -pad * dx};
  g.cells = {n + 2 * pad, n + 2 * pad, n + 2 * pad};
  std::map<std::string, double> params = {
      {"youngs_modulus", 1e6}, {"poisson_ratio", 0.3}, {"density", 1000}};
  if (model == "drucker_prager") params["friction_angle"] = 30;
  auto material = driver::mpm_material(model, params);
  mpm::SolverOptions opt;
  opt.max_dt = 1e-3;
  opt.allow_device = device;
  const BoundaryConfig floor = mpm::surface_collider("separate", {0, 0, 0}, {0, 0, 1}, 0.5);
  const geometry::Box block(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 1, 1));
  auto solver = driver::mpm_solver(comm, g, material, opt, {floor}, block, 2, {0.5, 0, -2});
  const long long particles = solver->count();
  double t = 0;
  for (int k = 0; k < 2; ++k) {
    const double dt = solver->stable_dt(1.0);
    solver->substep(t, dt);
    t += dt;
  }
  std::map<std::string, double> before;
  for (const char* p : kPhases) before[p] = solver->timers().total(p);
  MPI_Barrier(comm);
  const auto t0 = std::chrono::steady_clock::now();
  for (int k = 0; k < substeps; ++k) {
    const double dt = solver->stable_dt(1.0);
    solver->substep(t, dt);
    t += dt;
  }
  MPI_Barrier(comm);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double rate = static_cast<double>(particles) * substeps / wall;
  const double bytes = rate * kParticleBytes;
  std::string phases;
  for (const char* p : kPhases) {
    double local = solver->timers().total(p) - before[p], global = 0;
    MPI_Allreduce(&local, &global, 1, MPI_DOUBLE, MPI_MAX, comm);
    phases += fmt::format("{}\"{}\": {:.4f}", phases.empty() ? "" : ", ", p, global);
  }
  long long nodes = static_cast<long long>(solver->grid().ghosted_nodes().size());
  MPI_Allreduce(MPI_IN_PLACE, &nodes, 1, MPI_LONG_LONG, MPI_SUM, comm);
  return fmt::format(
      "    {{\"case\": \"{}\", \"model\": \"{}\", \"backend\": \"{}\", \"threads_per_rank\": {}, "
      "\"particles\": {}, \"grid_nodes_ghosted\": {}, "
      "\"substeps\": {}, \"seconds\": {:.4f},\n"
      "     \"particle_substeps_per_s\": {:.4g}, \"particle_substeps_per_s_per_rank\": {:.4g},\n"
      "     \"bytes_per_particle_substep\": {:.0f}, \"effective_GBps\": {:.3f}, "
      "\"fraction_of_stream\": {:.3f},\n"
      "     \"phase_seconds\": {{{}}}}}",
      name, model, solver->on_device() ? "gpu" : "cpu", exec::host_threads(), particles, nodes,
      substeps, wall, rate, rate / size, kParticleBytes, bytes / 1e9, bytes / stream, phases);
}

int run(long particles, int substeps, long stream_n, const std::string& json_path) {
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  const double stream = bench::stream_triad(static_cast<std::size_t>(stream_n));
  // The host kernels; on a rank with a GPU (CUDA build) also the device path, the host run
  // being its baseline in the same process.
  std::vector<std::string> cases;
  for (bool device : {false, true}) {
    if (device && !exec::use_device()) continue;
    cases.push_back(
        run_case("elastic_block", "fixed_corotated", particles, substeps, stream, size, device));
    cases.push_back(
        run_case("sand_block", "drucker_prager", particles, substeps, stream, size, device));
  }
  if (rank != 0) return 0;
  std::string all;
  for (const auto& c : cases) all += (all.empty() ? "" : ",\n") + c;
  const std::string json = fmt::format(
      "{{\n  \"benchmark\": \"mpm\",\n  \"ranks\": {},\n  \"threads_per_rank\": {},\n"
      "  \"device\": \"{}\",\n  \"stream_triad_GBps\": {:.3f},\n  \"cases\": [\n{}\n  ]\n}}\n",
      size, exec::host_threads(), exec::device_description(), stream / 1e9, all);
  std::fputs(json.c_str(), stdout);
  if (!json_path.empty()) {  // through a temporary, so a failed write leaves no half file
    const std::string tmp = json_path + ".tmp";
    std::FILE* f = std::fopen(tmp.c_str(), "w");
    const bool ok = f && std::fputs(json.c_str(), f) >= 0 && std::fclose(f) == 0 &&
                    std::rename(tmp.c_str(), json_path.c_str()) == 0;
    if (!ok) throw RuntimeError(fmt::format("{}: cannot write the benchmark JSON", json_path));
  }
  return 0;
}

}  // namespace
}  // namespace gen4d

int main(int argc, char** argv) {
  long particles = 1000000, stream_n = 20000000;
  int substeps = 20;
  std::string json;
  return gen4d::driver::main_with(
      argc, argv, "MPM particle-substeps/s vs STREAM triad, as JSON",
      [&](CLI::App& app) {
        app.add_option("--particles", particles, "Particles per case (8 per cell, a cube)")
            ->check(CLI::Range(1000L, 100000000L));
        app.add_option("--substeps", substeps, "Timed substeps")->check(CLI::Range(1, 100000));
        app.add_option("--json", json, "Also write the JSON to this file");
        app.add_option("--stream-n", stream_n, "STREAM array length per rank")
            ->check(CLI::Range(1000L, 1000000000L));
      },
      [&] { return gen4d::run(particles, substeps, stream_n, json); });
}
