// validate_diagnose_library — blind recordings for `gen4d diagnose` of the library effects
// CalculiX cannot produce (see diagnose_blind.py): viscoelasticity, coulomb_damping,
// contact_friction and quadratic air drag, with a null case beside them.
//
// Sample runs:
//   build/drivers/validate_diagnose_library --out cases --set full
//   build/drivers/validate_diagnose_library --out cases --set small --only coulomb-damping
//   python3 drivers/validation/diagnose_blind.py score --cases cases --gen4d build/drivers/gen4d
//
// Description:
//   1. The scene is diagnose_blind.py's cantilever (small: 10x2x2 voxels of 1 cm, 1 s; full:
//      20x4x4, 2 s): clamped at x = 0, gravity, a tip load pulse released at 0.3 s.
//   2. The recordings come from gen4d's own voxel model on a finer discretisation than the one
//      diagnose fits: voxels of h/2 and steps of dt/2 (8x the voxels, 2x the steps), so the
//      data carry a discretisation error of their own (an inverse crime would not). A first
//      run without any effect gives the scene's scales (the tip's lowest point, its swing
//      after the release, the rest frequency); each effect's truth is set from them, so that
//      the same cases mean the same thing on both beams:
//        viscoelasticity   g = 0.2, tau = 1 / omega (the Prony term's loss peaks at omega);
//        coulomb_damping   friction_accel = 0.015 omega^2 A (the swing A loses 6 % a cycle);
//        air_drag          quadratic only, at the drag per area that at half the peak tip speed
//                          equals the linear drag of a 2 % damping ratio;
//        contact_friction  a ground plane at 0.7 of the tip's lowest point, Coulomb mu 0.4.
//   3. Markers at surface grid nodes (one per stretch of the length, the last at the tip),
//      sampled at 100 Hz with jittered times, Gaussian noise; the nominal deck has E off by a
//      factor in [0.9, 1.1] and omits the effect.
//   4. Each effect run is compared with the effect-free run: the marker RMS difference in noise
//      sigmas (detect_snr) is in truth.json; below 3 the case is marked not detectable.
//   Per case, in OUT/CASE/: deck.toml, recording.csv, truth.json (the format of
//   diagnose_blind.py, which scores them); OUT/cases.json lists the cases. Files are written
//   under temporary names and renamed, so an interrupted run leaves no half-written case.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
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

constexpr double kRelease = 0.3;  // s, the tip pulse's end
constexpr double kRate = 100.0;   // samples per second
constexpr double kNu = 0.3, kRho = 1000.0, kG = 9.81;

struct Beam {
  std::array<int, 3> n;
  double h, E, end_time, dt;
  Vec3d force;
  int markers;
  double noise;  // m
};

Beam beam(const std::string& set) {
  if (set == "small") return {{10, 2, 2}, 0.01, 3.0e5, 1.0, 0.002, {0, 0.10, -0.08}, 6, 1e-4};
  return {{20, 4, 4}, 0.01, 5.0e5, 2.0, 0.002, {0, 0.6, -0.4}, 10, 1e-4};
}

std::string deck_text(const Beam& b, const std::string& name, double E) {
  const double L = b.n[0] * b.h, W = b.n[1] * b.h, H = b.n[2] * b.h;
  return fmt::format(
      R"(# Blind case {0}: nominal deck (one effect, if any, is left out).
[simulation]
name = "library-{0}"
dt = {1:.9g}
end_time = {2:.9g}
gravity = [0, 0, {3:.9g}]

[domain]
voxel_size = {4:.9g}
padding = 1

[[geometry]]
type = "box"
lo = [0, 0, 0]
hi = [{5:.9g}, {6:.9g}, {7:.9g}]

[material]
model = "stvk"
youngs_modulus = {8:.9g}
poisson_ratio = {9:.9g}
density = {10:.9g}

[[fixed]]
lo = [-1, -1, -1]
hi = [{11:.9g}, 1, 1]

[[force]]
lo = [{12:.9g}, -1, -1]
hi = [{13:.9g}, 1, 1]
force = [{14:.9g}, {15:.9g}, {16:.9g}]
start = 0
end = {17:.9g}
)",
      name, b.dt, b.end_time, -kG, b.h, L, W, H, E, kNu, kRho, 0.1 * b.h, L - 0.5 * b.h, L + 1,
      b.force[0], b.force[1], b.force[2], kRelease);
}

struct Case {
  std::string name, effect;  // effect empty: none
  std::vector<std::pair<std::string, double>> params;
  std::vector<std::string> scored;
  std::string notes;
};

struct Options {
  std::string out, set = "full";
  unsigned seed = 1;
  std::vector<std::string> only;

  //! Declares the command-line options.
  void add(CLI::App& app) {
    app.add_option("--out", out, "Output folder (cases.json and one folder per case)")->required();
    app.add_option("--set", set, "small (10x2x2 voxels, 1 s) or full (20x4x4, 2 s)")
        ->check(CLI::IsMember({"small", "full"}));
    app.add_option("--seed", seed, "Random seed (E factors, markers, sample times, noise)");
    app.add_option("--only", only, "Generate only these cases")->take_all();
  }
};

int generate(const Options& o) {
  const Beam b = beam(o.set);
  const double L = b.n[0] * b.h, W = b.n[1] * b.h, H = b.n[2] * b.h;
  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);

  // The recording's model: voxels of h/2, steps of dt/2, the true E.
  Config fine = parse_deck(deck_text(b, "truth", b.E), "<library truth deck>", ".", {});
  fine.voxel_size = 0.5 * b.h;
  fine.dt = 0.5 * b.dt;
  const diagnose::VoxelModel model(fine);
  const diagnose::Physics nominal = model.nominal();

  // Markers: surface grid nodes of the h grid, one per stretch of the length.
  std::vector<Vec3d> markers;
  for (int m = 0; m < b.markers; ++m) {
    const int i = std::max(1, static_cast<int>(std::lround((m + 1.0) * b.n[0] / b.markers)));
    const int face = static_cast<int>(uni(rng) * 4) % 4;
    const int span = face < 2 ? b.n[1] : b.n[2];
    const double s = b.h * (static_cast<int>(uni(rng) * (span + 1)) % (span + 1));
    Vec3d X{i * b.h, 0, 0};
    if (face < 2)
      X[1] = s, X[2] = face == 0 ? 0.0 : H;
    else
      X[1] = face == 2 ? 0.0 : W, X[2] = s;
    markers.push_back(X);
  }
  const std::vector<double> times = driver::jittered_times(b.end_time, kRate, rng);
  std::vector<diagnose::ChannelRequest> req;
  for (const Vec3d& X : markers) req.push_back({model.attach(X), false, times});
  // The tip probe: the bottom edge's middle at the free end, on the fine time grid.
  diagnose::ChannelRequest tip{model.attach({L, 0.5 * W, 0.0}), false, {}};
  for (double t = 0; t <= b.end_time + 1e-12; t += fine.dt) tip.t.push_back(t);
  req.push_back(tip);

  log::info("effect-free run on {} voxels (h/2), dt/2", model.voxels());
  const diagnose::Trace free = model.run(nominal, req);
  if (!free.ok) throw RuntimeError("the effect-free run failed: " + free.failure);
  const auto& tz = free.channel.back();
  double z_lo = 0, a = 0, v_max = 0;
  const std::size_t nt = tip.t.size();
  Vec3d mean_end{0, 0, 0};
  std::size_t n_end = 0;
  for (std::size_t k = 0; k < nt; ++k) {
    z_lo = std::min(z_lo, tz[3 * k + 2]);
    if (tip.t[k] >= 0.5 * (kRelease + b.end_time)) {
      for (int d = 0; d < 3; ++d) mean_end[d] += tz[3 * k + d];
      ++n_end;
    }
  }
  for (int d = 0; d < 3; ++d) mean_end[d] /= static_cast<double>(std::max<std::size_t>(n_end, 1));
  for (std::size_t k = 1; k < nt; ++k) {
    if (tip.t[k] < kRelease) continue;
    const double dy = tz[3 * k + 1] - mean_end[1], dz = tz[3 * k + 2] - mean_end[2];
    a = std::max(a, std::hypot(dy, dz));
    double v2 = 0;
    for (int d = 0; d < 3; ++d) v2 += std::pow((tz[3 * k + d] - tz[3 * k - 3 + d]) / fine.dt, 2);
    v_max = std::max(v_max, std::sqrt(v2));
  }
  Vec3d dir = b.force;
  const double fn = std::sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
  for (double& c : dir) c /= fn;
  const double omega = model.rest_frequency(nominal, dir);
  const double mass = kRho * L * W * H, area = model.exposed_area();
  const double b1 = 0.04 * omega * mass / area;  // linear drag of a 2 % damping ratio
  log::info(
      "scene: rest frequency {:.4g} Hz, tip swing after release {:.4g} m, peak tip speed {:.4g} "
      "m/s, tip's lowest point z = {:.4g} m",
      omega / (2 * M_PI), a, v_max, z_lo);

  std::vector<Case> cases = {
      {"none-h2", "", {}, {}, "only E is off; the data's voxels are h/2"},
      {"viscoelasticity",
       "viscoelasticity",
       {{"g", 0.2}, {"tau", 1.0 / omega}},
       {"g", "tau"},
       "one Prony term, tau = 1 / omega"},
      {"coulomb-damping",
       "coulomb_damping",
       {{"friction_accel", 0.015 * omega * omega * a}},
       {"friction_accel"},
       "dry friction: the swing loses 6 % a cycle"},
      {"air-drag-quadratic",
       "air_drag",
       {{"linear", 0.0}, {"quadratic", b1 / (0.5 * v_max)}},
       {"quadratic"},
       "quadratic drag only"},
      {"contact-friction",
       "contact_friction",
       {{"height", 0.7 * z_lo}, {"friction", 0.4}},
       {"height", "friction"},
       "ground plane at 0.7 of the tip's lowest point"},
  };
  driver::check_only(cases, o.only);

  fs::create_directories(o.out);
  std::string listing;
  for (const Case& c : cases) {
    const double E_factor = 0.9 + 0.2 * uni(rng);  // drawn for every case: subsets agree
    const unsigned noise_seed = static_cast<unsigned>(rng());
    if (!driver::wanted(o.only, c.name)) continue;
    // The effect as diagnose's library applies it (the parameters in its order).
    diagnose::Physics ph = nominal;
    if (!c.effect.empty()) {
      diagnose::EffectContext ctx;
      ctx.model = &model;
      ctx.base = nominal;
      std::vector<double> values;
      for (const auto& kv : c.params) values.push_back(kv.second);
      diagnose::find_effect(c.effect).apply("", values, ctx, ph);
    }
    log::info("case {}: {}", c.name, c.notes);
    const diagnose::Trace tr = c.effect.empty() ? free : model.run(ph, req);
    if (!tr.ok) throw RuntimeError(fmt::format("case {}: the run failed: {}", c.name, tr.failure));
    const double snr = driver::rms_apart(markers.size(), tr, free, b.noise);
    const diagnose::Recording rec =
        driver::noisy_recording(markers, times, tr, b.noise, noise_seed);
    const fs::path dir = fs::path(o.out) / c.name;
    fs::create_directories(dir);
    const double E_nom = b.E * E_factor;
    diagnose::write_recording_csv(rec, (dir / "recording.csv").string());
    write_atomic(dir / "deck.toml", deck_text(b, c.name, E_nom));
    const std::string params = driver::json_members(c.params),
                      scored = driver::json_strings(c.scored);
    const bool detectable = c.effect.empty() || snr >= 3.0;
    const std::string effect = c.effect.empty() ? "null" : "\"" + c.effect + "\"";
    write_atomic(
        dir / "truth.json",
        fmt::format(
            "{{\n  \"effect\": {},\n  \"parameters\": {{{}}},\n  \"scored_parameters\": [{}],\n"
            "  \"region\": null,\n  \"E_true\": {},\n  \"E_nominal\": {},\n  \"noise_sigma\": {},\n"
            "  \"element\": \"gen4d voxels h/2, dt/2\",\n  \"notes\": \"{}\",\n"
            "  \"detectable\": {},\n  \"detect_snr\": {},\n  \"separability\": null\n}}\n",
            effect, params, scored, json_number(b.E), json_number(E_nom), json_number(b.noise),
            c.notes, detectable ? "true" : "false", c.effect.empty() ? "null" : json_number(snr)));
    log::info(
        "case {}: E nominal {:.4g} (x{:.3f}), markers differ from the effect-free run by "
        "{:.3g} noise sd{}",
        c.name, E_nom, E_factor, snr, detectable ? "" : " (marked not detectable)");
    listing += fmt::format("{}    {{\"name\": \"{}\", \"effect\": {}}}",
                           listing.empty() ? "" : ",\n", c.name, effect);
  }
  write_atomic(fs::path(o.out) / "cases.json",
               fmt::format("{{\n  \"set\": \"library-{}\",\n  \"seed\": {},\n  \"element\": "
                           "\"gen4d voxels h/2\",\n  \"cases\": [\n{}\n  ]\n}}\n",
                           o.set, o.seed, listing));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return driver::main_with_options<Options>(
      argc, argv,
      "Blind recordings of the diagnose effects CalculiX cannot make, from gen4d's voxels at h/2",
      generate, driver::RankZero);
}
