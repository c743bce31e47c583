// validate_diagnose_mpm — blind recordings for `gen4d diagnose` on MPM scenes (solver.method =
// "mpm"): bodies that slide and strike, where the voxel model's clamps and springs do not
// apply and the MPM solver is the forward model.
//
// Sample runs:
//   build/drivers/validate_diagnose_mpm --out cases
//   build/drivers/validate_diagnose_mpm --out cases --only slide-friction
//   python3 drivers/validation/diagnose_blind.py score --cases cases --gen4d build/drivers/gen4d
//
// Description:
//   1. Scenes on a floor (a [[boundary]] surface_collider at z = 0 that the deck believes
//      frictionless):
//        slide   a jelly block (fixed corotated, 12 x 6 x 6 cm) launched along the floor at
//                1 m/s for 1 s;
//        strike  a bar (fixed corotated, 16 x 4 x 4 cm) thrown at the floor at 2.5 m/s,
//                tilted, for 0.5 s: it lands on one end, rotates and rebounds.
//   2. The recordings come from the MPM solver on a finer discretisation than the one diagnose
//      fits: cells of h/2 (8x the particles) and half the substep, so the data carry a
//      discretisation error of their own. A first run without any effect gives the scene's
//      scales (the peak von Mises stress); each effect's truth is set from them:
//        slide-friction    Coulomb friction 0.3 on the floor (the block stops in ~0.35 s);
//        slide-damping     mass damping alpha = 2 1/s;
//        slide-slope       the floor tilted by 3 degrees about y (gravity rotated);
//        strike-plasticity von Mises yield at 0.3 of the elastic run's peak stress,
//                          hardening 0.02 E;
//        strike-law        Neo-Hookean instead of fixed corotated;
//      and a third scene, the slide's block and floor again with draws of its own, for the
//      effects that act on every particle (so that the first two scenes' cases stay as they
//      were generated before):
//        drift-drag          quadratic surface drag 5 kg/m^3 (a dense medium);
//        drift-dry-friction  dry friction 0.5 m/s^2 on every particle, not the floor's;
//        and a null case per scene (only E is off).
//   3. Markers at surface points of the h grid, sampled at 200 Hz with jittered times,
//      Gaussian noise of 1e-4 m; the nominal deck has E off by a factor in [0.9, 1.1] and omits
//      the effect. Each effect run is compared with the effect-free run (detect_snr, in noise
//      sd), and the effect-free run with the deck's own discretisation at the true E
//      (model_error_snr): an effect below 3 sd or below twice that error (four times in
//      chi-square, diagnose's own margin for a misfit its discretisation could make) is marked
//      not detectable (the scorer then accepts "none" or "ambiguous" for it).
//   Per case, in OUT/CASE/: deck.toml, recording.csv, truth.json (diagnose_blind.py's format);
//   OUT/cases.json lists the cases. Files are written under temporary names and renamed.
#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "core/Deck.hpp"
#include "core/Error.hpp"
#include "core/Log.hpp"
#include "diagnose/Effects.hpp"
#include "diagnose/Forward.hpp"
#include "diagnose/Recording.hpp"
#include "validation/BlindCases.hpp"
#include "validation/DriverCommon.hpp"

using namespace gen4d;
namespace fs = std::filesystem;
using driver::json_number;
using driver::write_atomic;

namespace {

constexpr double kRate = 200.0;  // samples per second
constexpr double kNoise = 1e-4;  // m
constexpr double kNu = 0.3, kRho = 1000.0, kG = 9.81;

struct Scene {
  std::string name;
  Vec3d size;      // m
  Vec3d lo;        // the body's lowest corner
  Vec3d velocity;  // m/s
  Vec3d grid_lo, grid_hi;
  double E, end_time, h;
  int markers;
};

Scene scene(const std::string& name) {
  if (name == "slide")
    return {"slide",
            {0.12, 0.06, 0.06},
            {0, 0, 0},
            {1.0, 0, 0},
            {-0.08, -0.1, -0.08},
            {1.6, 0.16, 0.16},
            1.0e5,
            1.0,
            0.02,
            8};
  if (name == "drift") {  // the slide's block and floor, with draws of its own
    Scene d = scene("slide");
    d.name = "drift";
    return d;
  }
  return {"strike",
          {0.16, 0.04, 0.04},
          {0, 0, 0.04},
          {0.5, 0, -2.5},
          {-0.1, -0.1, -0.08},
          {0.44, 0.14, 0.28},
          1.0e5,
          0.5,
          0.02,
          8};
}

std::string deck_text(const Scene& s, const std::string& name, double E) {
  return fmt::format(
      R"(# Blind MPM case {0}: nominal deck (one effect, if any, is left out).
[simulation]
name = "mpm-{0}"
dt = 1e-3
end_time = {1:.9g}
gravity = [0, 0, {2:.9g}]

[solver]
method = "mpm"

[domain]
voxel_size = {3:.9g}

[mpm]
lo = [{4:.9g}, {5:.9g}, {6:.9g}]
hi = [{7:.9g}, {8:.9g}, {9:.9g}]
particles_per_axis = 2
velocity = [{10:.9g}, {11:.9g}, {12:.9g}]

[[geometry]]
type = "box"
lo = [{13:.9g}, {14:.9g}, {15:.9g}]
hi = [{16:.9g}, {17:.9g}, {18:.9g}]

[material]
model = "fixed_corotated"
youngs_modulus = {19:.9g}
poisson_ratio = {20:.9g}
density = {21:.9g}

[[boundary]]   # the floor, believed frictionless
type = "surface_collider"
point = [0, 0, 0]
normal = [0, 0, 1]
surface = "separate"
friction = 0
)",
      name, s.end_time, -kG, s.h, s.grid_lo[0], s.grid_lo[1], s.grid_lo[2], s.grid_hi[0],
      s.grid_hi[1], s.grid_hi[2], s.velocity[0], s.velocity[1], s.velocity[2], s.lo[0], s.lo[1],
      s.lo[2], s.lo[0] + s.size[0], s.lo[1] + s.size[1], s.lo[2] + s.size[2], E, kNu, kRho);
}

struct Case {
  std::string name, scene, effect, variant;  // effect empty: none
  std::vector<std::pair<std::string, double>> params;
  std::vector<std::string> scored;
  std::string notes;
};

struct Options {
  std::string out;
  unsigned seed = 1;
  std::vector<std::string> only;

  //! Declares the command-line options.
  void add(CLI::App& app) {
    app.add_option("--out", out, "Output folder (cases.json and one folder per case)")->required();
    app.add_option("--seed", seed, "Random seed (E factors, markers, sample times, noise)");
    app.add_option("--only", only, "Generate only these cases")->take_all();
  }
};

int generate(const Options& o) {
  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  const double tilt = 3.0 * M_PI / 180;
  const std::vector<Case> cases = {
      {"slide-none", "slide", "", "", {}, {}, "only E is off; the data's cells are h/2"},
      {"slide-friction",
       "slide",
       "contact_friction",
       "",
       {{"height", 0.0}, {"friction", 0.3}},
       {"friction"},
       "Coulomb friction 0.3 on the floor the deck believes frictionless"},
      {"slide-damping",
       "slide",
       "damping",
       "mass",
       {{"alpha", 2.0}},
       {"alpha"},
       "mass damping 2 1/s"},
      {"slide-slope",
       "slide",
       "gravity",
       "",
       {{"gx", kG * std::sin(tilt)}, {"gy", 0.0}, {"gz", -kG * std::cos(tilt)}},
       {"gx"},
       "the floor tilted by 3 degrees (downhill along +x); gz, 0.14 % from the deck's, is not "
       "scored: a block on the floor shows it only through its sag, which gives g / E"},
      {"strike-none", "strike", "", "", {}, {}, "only E is off; the data's cells are h/2"},
      {"strike-plasticity",
       "strike",
       "plasticity",
       "",
       {{"yield_stress", 0.3}, {"hardening", 0.02}},  // scaled below
       {"yield_stress"},
       "von Mises yield at 0.3 of the elastic run's peak stress, hardening 0.02 E"},
      {"strike-law", "strike", "material_law", "neo_hookean", {}, {}, "Neo-Hookean data"},
      {"drift-drag",
       "drift",
       "air_drag",
       "",
       {{"linear", 0.0}, {"quadratic", 5.0}},
       {"quadratic"},
       "quadratic surface drag 5 kg/m^3 (a dense medium; air is about 0.6): the block slows "
       "as v0 / (1 + k v0 t), k = 0.42 1/m"},
      {"drift-dry-friction",
       "drift",
       "coulomb_damping",
       "",
       {{"friction_accel", 0.5}},
       {"friction_accel"},
       "dry friction 0.5 m/s^2 opposing every particle's velocity (not the floor's)"},
  };
  driver::check_only(cases, o.only);
  fs::create_directories(o.out);
  std::string listing;
  // Scenes in this order, so that a later scene's cases leave the earlier ones' draws alone.
  for (const std::string scene_name : {"slide", "strike", "drift"}) {
    const Scene s = scene(scene_name);
    bool scene_wanted = o.only.empty();
    for (const auto& c : cases)
      scene_wanted =
          scene_wanted || (c.scene == scene_name &&
                           std::find(o.only.begin(), o.only.end(), c.name) != o.only.end());
    // The recording's model: cells of h/2 (and so half the substep), the true E.
    Config fine = parse_deck(deck_text(s, "truth", s.E), "<mpm truth deck>", ".", {});
    fine.voxel_size = 0.5 * s.h;
    const diagnose::MpmModel model(fine);
    const diagnose::Physics nominal = model.nominal();
    // Markers: points of the h grid on the body's faces (not the floor side), random.
    std::vector<Vec3d> markers;
    const std::array<int, 3> n = {static_cast<int>(std::lround(s.size[0] / s.h)),
                                  static_cast<int>(std::lround(s.size[1] / s.h)),
                                  static_cast<int>(std::lround(s.size[2] / s.h))};
    for (int m = 0; m < s.markers; ++m) {
      const int face = static_cast<int>(uni(rng) * 3) % 3;  // top, y = 0 side, y = W side
      Vec3d X = s.lo;
      X[0] += s.h * (static_cast<int>(uni(rng) * (n[0] + 1)) % (n[0] + 1));
      if (face == 0) {
        X[1] += s.h * (static_cast<int>(uni(rng) * (n[1] + 1)) % (n[1] + 1));
        X[2] += s.size[2];
      } else {
        X[1] += face == 1 ? 0.0 : s.size[1];
        X[2] += s.h * (static_cast<int>(uni(rng) * (n[2] + 1)) % (n[2] + 1));
      }
      markers.push_back(X);
    }
    const std::vector<double> times = driver::jittered_times(s.end_time, kRate, rng);
    std::vector<diagnose::ChannelRequest> req;
    for (const Vec3d& X : markers) req.push_back({model.attach(X), false, times});
    if (!scene_wanted) {
      for (const auto& c : cases)  // keep the draws of the other scene's cases
        if (c.scene == scene_name) uni(rng), rng();
      continue;
    }
    log::info("scene {}: effect-free run, cells of h/2, substep {:.3g} s", scene_name,
              model.substep());
    const diagnose::Trace free = model.run(nominal, req);
    if (!free.ok) throw RuntimeError("the effect-free run failed: " + free.failure);
    log::info("scene {}: peak von Mises stress {:.4g} Pa, peak speed {:.4g} m/s", scene_name,
              free.max_mises, free.max_speed);
    // The error of the deck's own discretisation (cells of h, its substep) at the true E: an
    // effect whose signature is below it cannot be told from the model's error.
    const diagnose::MpmModel coarse(
        parse_deck(deck_text(s, "truth", s.E), "<mpm h deck>", ".", {}));
    std::vector<diagnose::ChannelRequest> creq;
    for (const Vec3d& X : markers) creq.push_back({coarse.attach(X), false, times});
    const diagnose::Trace at_h = coarse.run(coarse.nominal(), creq);
    if (!at_h.ok) throw RuntimeError("the effect-free run at h failed: " + at_h.failure);
    const double model_error = driver::rms_apart(markers.size(), at_h, free, kNoise);
    log::info("scene {}: the deck's cells (h) differ from h/2 by {:.3g} noise sd rms", scene_name,
              model_error);
    for (const Case& c : cases) {
      if (c.scene != scene_name) continue;
      const double E_factor = 0.9 + 0.2 * uni(rng);
      const unsigned noise_seed = static_cast<unsigned>(rng());
      if (!driver::wanted(o.only, c.name)) continue;
      diagnose::Physics ph = nominal;
      std::vector<std::pair<std::string, double>> params = c.params;
      if (c.effect == "plasticity") {
        params[0].second *= free.max_mises;
        params[1].second *= s.E;
      }
      if (!c.effect.empty()) {
        diagnose::EffectContext ctx;
        ctx.model = &model;
        ctx.base = nominal;
        ctx.max_mises = free.max_mises;
        std::vector<double> values;
        for (const auto& kv : params) values.push_back(kv.second);
        diagnose::find_effect(c.effect).apply(c.variant, values, ctx, ph);
      }
      log::info("case {}: {}", c.name, c.notes);
      const diagnose::Trace tr = c.effect.empty() ? free : model.run(ph, req);
      if (!tr.ok)
        throw RuntimeError(fmt::format("case {}: the run failed: {}", c.name, tr.failure));
      const double snr = driver::rms_apart(markers.size(), tr, free, kNoise);
      const diagnose::Recording rec =
          driver::noisy_recording(markers, times, tr, kNoise, noise_seed);
      const fs::path dir = fs::path(o.out) / c.name;
      fs::create_directories(dir);
      const double E_nom = s.E * E_factor;
      diagnose::write_recording_csv(rec, (dir / "recording.csv").string());
      write_atomic(dir / "deck.toml", deck_text(s, c.name, E_nom));
      const std::string pj = driver::json_members(params), scored = driver::json_strings(c.scored);
      // Twice the model's error in rms, four times in chi-square: diagnose's own rule for a
      // misfit the model's discretisation could make (kUnidentifiedFactor).
      const bool detectable = c.effect.empty() || (snr >= 3.0 && snr >= 2 * model_error);
      const std::string effect = c.effect.empty() ? "null" : "\"" + c.effect + "\"";
      const std::vector<double> box =  // factor, lo, hi
          diagnose::effect_terms(ph, diagnose::find_effect("heterogeneity"));
      const std::string region =
          !box.empty() ? fmt::format("[[{}, {}, {}], [{}, {}, {}]]", json_number(box[1]),
                                     json_number(box[2]), json_number(box[3]), json_number(box[4]),
                                     json_number(box[5]), json_number(box[6]))
                       : std::string("null");
      write_atomic(
          dir / "truth.json",
          fmt::format("{{\n  \"effect\": {},\n  \"variant\": {},\n  \"parameters\": {{{}}},\n"
                      "  \"scored_parameters\": [{}],\n  \"region\": {},\n  \"E_true\": {},\n"
                      "  \"E_nominal\": {},\n  \"noise_sigma\": {},\n"
                      "  \"element\": \"gen4d MPM, cells h/2, dt/2\",\n  \"notes\": \"{}\",\n"
                      "  \"detectable\": {},\n  \"detect_snr\": {},\n  \"model_error_snr\": {},\n"
                      "  \"separability\": null\n}}\n",
                      effect, c.variant.empty() ? "null" : "\"" + c.variant + "\"", pj, scored,
                      region, json_number(s.E), json_number(E_nom), json_number(kNoise), c.notes,
                      detectable ? "true" : "false", c.effect.empty() ? "null" : json_number(snr),
                      json_number(model_error)));
      log::info(
          "case {}: E nominal {:.4g} (x{:.3f}), markers differ from the effect-free run by "
          "{:.3g} noise sd{}",
          c.name, E_nom, E_factor, snr,
          detectable ? "" : " (marked not detectable: below 3 or the deck's discretisation error)");
      listing += fmt::format("{}    {{\"name\": \"{}\", \"effect\": {}}}",
                             listing.empty() ? "" : ",\n", c.name, effect);
    }
  }
  write_atomic(fs::path(o.out) / "cases.json",
               fmt::format("{{\n  \"set\": \"mpm\",\n  \"seed\": {},\n  \"element\": "
                           "\"gen4d MPM h/2\",\n  \"cases\": [\n{}\n  ]\n}}\n",
                           o.seed, listing));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return driver::main_with_options<Options>(
      argc, argv, "Blind recordings of MPM scenes for gen4d diagnose, from the MPM solver at h/2",
      generate, driver::RankZero);
}
