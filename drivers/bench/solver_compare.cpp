// bench_solvers — time per frame of ElastoGen vs the Newton reference at equal accuracy on
// a beam of >= 100k DoFs, printed as JSON (a benchmark, not a test: it measures, it does not
// assert a speed).
//
// Sample runs:
//   mpirun -np 2 build/drivers/bench_solvers       # 100 x 20 x 20 voxels, 134k DoFs, 20 frames
//   OMP_NUM_THREADS=2 build/drivers/bench_solvers  # 1 rank x 2 threads
//   build/drivers/bench_solvers --cells 8 --frames 4        # small
//
// Description:
//   1. Beam 1.0 x 0.2 x 0.2 m clamped at x = 0, corotated (analytic target), E = 1e7 Pa,
//      nu = 0.3, rho = 1000, released under gravity; one frame = one step of dt = 0.01 s.
//   2. The Newton reference (PETSc SNES, CG + GAMG) runs the same `frames` steps: the ground
//      truth and the baseline time per frame.
//   3. ElastoGen runs the same frames with the accuracy tolerance at 1e-1, tightened by
//      steps of ~3x (down to 1e-4) until the tip trajectory is within `--accuracy`
//      (default 1 %) of Newton's (max |z_E - z_N| / max |z_N - z_N(0)|): the loosest setting
//      that meets the target; that run's time per frame is compared.
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "core/Deck.hpp"
#include "core/DeckText.hpp"
#include "core/Log.hpp"
#include "core/ParallelFor.hpp"
#include "elastogen/Simulation.hpp"
#include "validation/DriverCommon.hpp"

using namespace gen4d;

namespace {

struct Options {
  int cells = 20;  //!< voxels through the 0.2 m thickness (beam is 5x longer)
  int frames = 20;
  double accuracy = 0.01;
  std::string relaxation = "jacobi";  //!< ElastoGen's global-step sweeps

  //! Declares the command-line options.
  void add(CLI::App& app) {
    app.add_option("--cells", cells, "Voxels through the beam's thickness (length: 5x)")
        ->check(CLI::Range(2, 400));
    app.add_option("--frames", frames, "Frames (steps of 0.01 s)")->check(CLI::Range(1, 10000));
    app.add_option("--accuracy", accuracy, "Tip error ElastoGen must reach vs Newton");
    app.add_option("--relaxation", relaxation, "ElastoGen's sweeps: jacobi or chebyshev")
        ->check(CLI::IsMember({"jacobi", "chebyshev"}));
  }
};

Config beam(const Options& o, const std::string& method, double accuracy_tolerance) {
  BeamDeck b;
  b.end_time = 0.01 * o.frames;
  b.voxel_size = 0.2 / o.cells;
  b.hi = {1.0, 0.2, 0.2};
  b.law = "fixed_corotated";
  b.target = "analytic";
  b.youngs_modulus = 1e7;
  b.method = method;
  b.solver.set("relaxation", o.relaxation)
      .set("accuracy_tolerance", accuracy_tolerance)
      .set("max_extra_outer", 1000);
  return parse_deck(b.text().str(), "<bench beam>", ".");
}

struct Run {
  std::vector<double> tip;
  double seconds = 0;
  long loops = 0, sweeps = 0, dofs = 0;
  std::string phases;  //!< per-phase seconds as a JSON object body
};

Run simulate(const Options& o, const std::string& method, double tol) {
  const Config cfg = beam(o, method, tol);
  log::set_quiet(true);
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
  log::set_quiet(false);
  Run r;
  const auto& d = sim.grid().global_nodes();
  r.dofs = 3 * d[0] * d[1] * d[2];
  r.tip.push_back(driver::end_face_mean(sim, 2));
  MPI_Barrier(MPI_COMM_WORLD);
  const double t0 = MPI_Wtime();
  for (int s = 0; s < o.frames; ++s) {
    const auto st = sim.dynamics().step(s * cfg.dt);
    r.loops += st.outer;
    r.sweeps += st.sweeps;
    r.tip.push_back(driver::end_face_mean(sim, 2));
  }
  r.seconds = MPI_Wtime() - t0;
  for (const auto& [name, sec] : sim.timers().totals())
    r.phases += fmt::format("{}\"{}\": {:.3f}", r.phases.empty() ? "" : ", ", name, sec);
  return r;
}

double tip_error(const Run& a, const Run& ref) {
  double err = 0, amp = 0;
  for (std::size_t s = 0; s < ref.tip.size(); ++s) {
    err = std::max(err, std::fabs(a.tip[s] - ref.tip[s]));
    amp = std::max(amp, std::fabs(ref.tip[s] - ref.tip[0]));
  }
  return err / amp;
}

int run(const Options& o) {
  int ranks = 1, rank = 0;
  MPI_Comm_size(MPI_COMM_WORLD, &ranks);
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  const Run n = simulate(o, "newton", 1e-3);
  log::info("newton: {:.3f} s/frame, {} DoFs", n.seconds / o.frames, n.dofs);
  // Equal accuracy: the loosest accuracy tolerance whose tip trajectory is within the target.
  Run e;
  double tol = 0, err = 0;
  for (double t : {1e-1, 3e-2, 1e-2, 3e-3, 1e-3, 3e-4, 1e-4}) {
    e = simulate(o, "elastogen", t);
    tol = t;
    err = tip_error(e, n);
    log::info("elastogen accuracy_tolerance {:.1e}: {:.3f} s/frame, tip error {:.3f} %", t,
              e.seconds / o.frames, 100 * err);
    if (err <= o.accuracy) break;
  }
  const double speedup = n.seconds / e.seconds;
  if (rank == 0)
    std::printf(
        "{\n  \"benchmark\": \"elastogen_vs_newton\",\n  \"ranks\": %d,\n"
        "  \"threads_per_rank\": %d,\n  \"dofs\": %ld,\n"
        "  \"frames\": %d,\n  \"dt\": 0.01,\n  \"target_tip_error\": %g,\n"
        "  \"newton\": {\"seconds_per_frame\": %.4f, \"newton_iterations_per_frame\": %.2f, "
        "\"krylov_iterations_per_frame\": %.1f, \"phases\": {%s}},\n"
        "  \"elastogen\": {\"relaxation\": \"%s\", \"seconds_per_frame\": %.4f, "
        "\"accuracy_tolerance\": %.2e, "
        "\"tip_error\": %.5f, \"loops_per_frame\": %.2f, \"sweeps_per_frame\": %.1f, "
        "\"phases\": {%s}},\n  \"speedup_elastogen_over_newton\": %.3f\n}\n",
        ranks, exec::host_threads(), n.dofs, o.frames, o.accuracy, n.seconds / o.frames,
        double(n.loops) / o.frames, double(n.sweeps) / o.frames, n.phases.c_str(),
        o.relaxation.c_str(), e.seconds / o.frames, tol, err, double(e.loops) / o.frames,
        double(e.sweeps) / o.frames, e.phases.c_str(), speedup);
  return err <= o.accuracy ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  return driver::main_with_options<Options>(
      argc, argv, "Time per frame: ElastoGen vs Newton reference at equal accuracy", run);
}
