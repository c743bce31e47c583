// Speed of the `gen4d diagnose` forward model (one serial run of VoxelModel), printed as JSON.
// The scene is the acceptance case of diagnose: a 20x4x4-voxel cantilever (h = 1 cm, StVK,
// E = 5e5 Pa), clamped at x = 0, under gravity, a tip pulse released at 0.3 s, 2 s at
// dt = 2 ms, 10 sampled surface points. Runs, each timed as the best of --repeat:
//   baseline   the linear law at a load 1e-4 of the case's: every step converges in one
//              Newton iteration on the rest stiffness, so this is the floor of a step's cost
//              (one internal-force pass and one back-substitution);
//   nominal    the case itself (8 cm tip motion: large rotations, a refreshed tangent);
//   damping    with Rayleigh stiffness damping (beta = 2e-3 s), as the fits run it;
//   neo_hookean the case with the Neo-Hookean law;
//   corotated  the case with the fixed-corotated law (a polar decomposition per stress);
//   plastic    with von Mises plasticity (yield 10 kPa, hardening 20 kPa), the slowest law.
// Per run: wall seconds, steps, Newton iterations per step, factorizations, steps redone
// with fresh tangents (restarts), and the split
// over phases (internal forces, tangent, factorization, back-substitution, rest). Each run
// is timed twice: with the model's element (incompatible modes, half-consistent mass) and,
// as the baseline in the same process, with the plain trilinear element and lumped masses
// ("trilinear"), with the cost ratio of the two. The elastic runs under the laws the vector
// kernel has (StVK, Neo-Hookean, corotated) are timed a third time in the scalar element
// loop ("scalar_element_loop"), the baseline of the vector kernel, with whether the two runs
// agree bit for bit.
// --voxel-size 0.005 times the model of diagnose's discretisation check (h/2: 8x the voxels),
// --newton-tolerance another Newton stop (diagnose's check runs its h/2 model at 1e-4),
// --refresh-contraction another rule for rebuilding the lagged tangent (a correction that
// shrinks by less than this factor rebuilds it; the default 0.5),
// --isa the instruction set of the element kernel and of the block LDL^T (baseline, avx2,
// avx512f; default: the one each picks; the LDL^T has no AVX-512 build and keeps its own), --case
// one of the runs alone, --poisson another Poisson ratio (a calibration that absorbs a soft region
// bends it to its bound, 0.45).
// --deck FILE --point X,Y,Z times a deck instead: one accelerometer at the point, sampled at
// --rate Hz over the deck's end_time, with the deck's law, then (baselines, same process) the
// same iterated to the Newton tolerance (a linear problem takes one solve a step otherwise:
// Physics::linear_single_solve) and with fixed_corotated, the nonlinear law whose tangent the
// Newton iteration rebuilds (e.g. inputs/strip_plain.toml, the thin strip: 6 s at 500 Hz);
// pre-loads released over 2 ms.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>

#include "core/Deck.hpp"
#include "core/Error.hpp"
#include "core/DeckText.hpp"
#include "forward/BlockLDLT.hpp"
#include "diagnose/Effects.hpp"
#include "forward/ElementKernel.hpp"
#include "diagnose/Forward.hpp"
#include "validation/DriverCommon.hpp"

namespace gen4d {
namespace {

//! The acceptance cantilever of diagnose at voxel size `h` and Poisson ratio `nu`.
Config bench_deck(double h, double nu) {
  BeamDeck b;
  b.dt = 0.002;
  b.end_time = 2;
  b.gravity = Vec3d{0, 0, -9.81};
  b.voxel_size = h;
  b.padding = 1;
  b.hi = {0.2, 0.04, 0.04};
  b.law = "stvk";
  b.youngs_modulus = 5e5;
  b.poisson_ratio = nu;
  const std::string text = b.text()
                               .array("force")
                               .set("lo", Vec3d{0.195, -1, -1})
                               .set("hi", Vec3d{1.2, 1, 1})
                               .set("force", Vec3d{0, -0.72, -0.48})
                               .set("start", 0.0)
                               .set("end", 0.3)
                               .str();
  return parse_deck(text, "<diagnose bench deck>", ".", {});
}

struct Result {
  double wall = 1e300;
  diagnose::Trace trace;
};

Result time_run(const char* name, const diagnose::VoxelModel& model, const diagnose::Physics& ph,
                const std::vector<diagnose::ChannelRequest>& req, int repeat) {
  Result r;
  for (int k = 0; k < repeat; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    diagnose::Trace tr = model.run(ph, req);
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (!tr.ok) throw std::runtime_error(std::string(name) + " run failed: " + tr.failure);
    if (s < r.wall) r.wall = s, r.trace = std::move(tr);
  }
  return r;
}

std::string json(const char* name, const Result& r) {
  const auto& t = r.trace;
  const double rest = r.wall - t.time_internal - t.time_tangent - t.time_factor - t.time_solve;
  return fmt::format(
      "    \"{}\": {{\"wall_s\": {:.4f}, \"steps\": {}, \"newton_per_step\": {:.3f}, "
      "\"factorizations\": {}, \"restarts\": {}, \"internal_s\": {:.4f}, \"tangent_s\": {:.4f}, "
      "\"factor_s\": {:.4f}, \"solve_s\": {:.4f}, \"other_s\": {:.4f}}}",
      name, r.wall, t.steps, static_cast<double>(t.newton_iterations) / std::max(1L, t.steps),
      t.factorizations, t.restarts, t.time_internal, t.time_tangent, t.time_factor, t.time_solve,
      rest);
}

//! --deck mode: the deck's run with its own law, iterated, then with fixed_corotated, as JSON.
int time_deck(const std::string& path, const Vec3d& point, double rate, int repeat) {
  const Config cfg = load_deck(path, {});
  const diagnose::VoxelModel model(cfg);
  if (!model.inside(point)) throw InputError(path + ": --point is not on the body");
  std::vector<diagnose::ChannelRequest> req(1);
  req[0].at = model.attach(point);
  req[0].acceleration = true;
  const long n = std::lround(cfg.end_time * rate);
  for (long k = 0; k < n; ++k) req[0].t.push_back(static_cast<double>(k) / rate);
  diagnose::Physics own = model.nominal();
  own.release_duration = 0.002;  // a pre-load let go over 2 ms, as diagnose starts its fit
  diagnose::Physics corotated = own;
  corotated.law = "fixed_corotated";
  diagnose::Physics iterated = own;
  iterated.linear_single_solve = false;
  const Result r = time_run("deck", model, own, req, repeat);
  const Result it = time_run("iterated", model, iterated, req, repeat);
  std::string baseline = json("iterated", it) + ",\n";
  try {
    const Result c = time_run("fixed_corotated", model, corotated, req, repeat);
    baseline += json("fixed_corotated", c) +
                fmt::format("\n  }},\n  \"corotated_over_deck\": {:.3f}\n}}", c.wall / r.wall);
  } catch (const std::runtime_error& e) {  // the nonlinear law may not converge on thin parts
    baseline += fmt::format("    \"fixed_corotated\": {{\"failed\": \"{}\"}}\n  }}\n}}", e.what());
  }
  std::printf("{\n  \"deck\": \"%s\", \"voxels\": %zu, \"nodes\": %zu, \"samples\": %ld,\n",
              path.c_str(), model.voxels(), model.nodes(), n);
  std::printf("  \"runs\": {\n%s,\n%s\n", json(own.law.c_str(), r).c_str(), baseline.c_str());
  return 0;
}

}  // namespace
}  // namespace gen4d

int main(int argc, char** argv) {
  using namespace gen4d;
  int repeat = 3;
  double voxel_size = 0.01, poisson = 0.3, newton_tolerance = 0, refresh = 0;
  std::string only, isa, deck;
  std::vector<double> point;
  double rate = 500;
  return driver::main_with(
      argc, argv, "Speed of the gen4d diagnose forward model (JSON on stdout)",
      [&](CLI::App& app) {
        app.add_option("--repeat", repeat, "runs per case, best time kept")
            ->check(CLI::Range(1, 100));
        app.add_option("--voxel-size", voxel_size, "voxel size of the 0.2 x 0.04 x 0.04 m beam")
            ->check(CLI::Range(0.002, 0.02));
        app.add_option("--poisson", poisson, "Poisson ratio")->check(CLI::Range(0.0, 0.49));
        app.add_option("--newton-tolerance", newton_tolerance,
                       "Newton's stop in voxel sizes (0: the model's default)")
            ->check(CLI::Range(0.0, 1e-2));
        app.add_option("--refresh-contraction", refresh,
                       "tangent rebuilt when a correction shrinks by less (0: the default)")
            ->check(CLI::Range(0.0, 1.0));
        app.add_option("--isa", isa,
                       "instruction set of the element kernel and LDL^T (default: the best)")
            ->check(CLI::IsMember(diagnose::element_kernel_isas()));
        app.add_option("--deck", deck, "time this deck instead (with --point)")
            ->check(CLI::ExistingFile);
        app.add_option("--point", point, "the sampled accelerometer's reference point X,Y,Z")
            ->expected(3)
            ->delimiter(',');
        app.add_option("--rate", rate, "samples per second (--deck)")->check(CLI::Range(1.0, 1e6));
        app.add_option("--case", only, "only this run")
            ->check(CLI::IsMember(
                {"baseline", "nominal", "damping", "neo_hookean", "corotated", "plastic"}));
      },
      [&]() -> int {
        int rank = 0;
        MPI_Comm_rank(MPI_COMM_WORLD, &rank);
        if (rank != 0) return 0;  // serial: one run is one process's work
        if (!deck.empty()) {
          if (point.size() != 3) throw InputError("--deck needs --point X,Y,Z");
          return time_deck(deck, {point[0], point[1], point[2]}, rate, repeat);
        }
        if (!isa.empty()) {
          diagnose::set_element_kernel_isa(isa);
          const auto ldlt = diagnose::BlockLDLT::isas();
          if (std::find(ldlt.begin(), ldlt.end(), isa) != ldlt.end())
            diagnose::BlockLDLT::set_isa(isa);
        }
        const Config cfg = bench_deck(voxel_size, poisson);
        const diagnose::VoxelModel model(cfg);
        std::vector<diagnose::ChannelRequest> req;
        const double t_end = cfg.end_time;
        for (int m = 0; m < 10; ++m) {
          diagnose::ChannelRequest c;
          c.at = model.attach({0.02 * (m + 1) - 0.001, m % 2 ? 0.04 : 0.0, 0.04});
          for (int k = 0; k <= 200; ++k) c.t.push_back(t_end * k / 200.0);
          req.push_back(std::move(c));
        }
        diagnose::Physics base = model.nominal();
        base.law = "linear";
        base.load_scale = 1e-4;
        base.gravity = {0, 0, -9.81e-4};
        diagnose::Physics nominal = model.nominal();
        if (newton_tolerance > 0)
          base.newton_tolerance = nominal.newton_tolerance = newton_tolerance;
        if (refresh > 0) base.refresh_contraction = nominal.refresh_contraction = refresh;
        diagnose::Physics damped = nominal;
        diagnose::set_effect_terms(damped, "damping", {0, 2e-3});
        diagnose::Physics neo = nominal;
        neo.law = "neo_hookean";
        diagnose::Physics corotated = nominal;
        corotated.law = "corotated";
        diagnose::Physics plastic = nominal;
        diagnose::set_effect_terms(plastic, "plasticity", {1e4, 2e4});
        auto trilinear = [](diagnose::Physics p) {
          p.element = diagnose::Element::trilinear;
          p.consistent_mass_fraction = 0;
          return p;
        };
        constexpr int kRuns = 6;
        const char* names[kRuns] = {"baseline",    "nominal",   "damping",
                                    "neo_hookean", "corotated", "plastic"};
        const diagnose::Physics phys[kRuns] = {base, nominal, damped, neo, corotated, plastic};
        diagnose::VoxelModel scalar_model(cfg);
        scalar_model.set_vector_kernels(false);
        std::string runs, old_runs, ratios, scalar_runs;
        double wall[kRuns] = {};
        for (int k = 0; k < kRuns; ++k) {
          if (!only.empty() && only != names[k]) continue;
          const Result r = time_run(names[k], model, phys[k], req, repeat);
          const Result o = time_run(names[k], model, trilinear(phys[k]), req, repeat);
          const std::string& law = phys[k].law;
          if ((law == "stvk" || law == "neo_hookean" || law == "corotated") &&
              !std::isfinite(diagnose::model_terms(phys[k]).yield_stress)) {
            // The same run in the scalar element loop: the vector kernel's baseline, and
            // whether the two agree bit for bit.
            const Result sr = time_run(names[k], scalar_model, phys[k], req, repeat);
            const bool same = sr.trace.channel == r.trace.channel;
            scalar_runs += fmt::format(
                "{}    \"{}\": {{\"wall_s\": {:.4f}, \"internal_s\": {:.4f}, "
                "\"vector_internal_speedup\": {:.2f}, \"vector_run_speedup\": {:.3f}, "
                "\"bit_identical\": {}}}",
                scalar_runs.empty() ? "" : ",\n", names[k], sr.wall, sr.trace.time_internal,
                sr.trace.time_internal / r.trace.time_internal, sr.wall / r.wall, same);
          }
          wall[k] = r.wall;
          const char* sep = runs.empty() ? "" : ",\n";
          runs += sep + json(names[k], r);
          old_runs += sep + json(names[k], o);
          ratios += fmt::format("{}\"{}\": {:.3f}", ratios.empty() ? "" : ", ", names[k],
                                r.wall / o.wall);
        }
        std::printf(
            "{\n  \"model\": {\"voxels\": %zu, \"nodes\": %zu, \"repeat\": %d, "
            "\"element_kernel\": \"%s\", \"block_ldlt\": \"%s\"},\n",
            model.voxels(), model.nodes(), repeat, diagnose::element_kernel_isa().c_str(),
            diagnose::BlockLDLT::isa().c_str());
        std::printf("  \"runs\": {\n%s\n  },\n", runs.c_str());
        std::printf("  \"trilinear\": {\n%s\n  },\n", old_runs.c_str());
        std::printf("  \"cost_over_trilinear\": {%s},\n", ratios.c_str());
        if (!scalar_runs.empty())
          std::printf("  \"scalar_element_loop\": {\n%s\n  },\n", scalar_runs.c_str());
        if (wall[0] > 0 && wall[1] > 0)
          std::printf("  \"nominal_over_baseline\": %.3f,\n", wall[1] / wall[0]);
        std::printf("  \"voxel_size\": %g,\n  \"poisson_ratio\": %g\n}\n", voxel_size, poisson);
        return 0;
      });
}
