#include "diagnose/Report.hpp"

#include "forward/ElementKernel.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <sstream>

#include "core/Error.hpp"
#include "core/TextFile.hpp"
#include "io/Plot.hpp"
#include "io/Xdmf.hpp"

namespace gen4d::diagnose {

ThinBody thin_body(const Diagnosis& d) {
  ThinBody b;
  for (int a = 0; a < 3; ++a) {
    const double e = d.body.hi[a] - d.body.lo[a];
    if (e > d.body.hi[b.long_axis] - d.body.lo[b.long_axis]) b.long_axis = a;
    if (e < d.body.hi[b.thin_axis] - d.body.lo[b.thin_axis]) b.thin_axis = a;
  }
  b.length = d.body.hi[b.long_axis] - d.body.lo[b.long_axis];
  b.thickness = d.body.hi[b.thin_axis] - d.body.lo[b.thin_axis];
  b.thin = b.thickness > 0 && b.length >= kThinAspect * b.thickness && d.youngs_nominal > 0 &&
           d.youngs_modulus > 0;
  if (b.thin) b.equivalent_thickness = b.thickness * std::sqrt(d.youngs_modulus / d.youngs_nominal);
  return b;
}

namespace {

std::string jnum(double v) {
  if (!std::isfinite(v)) return "null";
  return fmt::format("{:.9g}", v);
}

std::string jstr(const std::string& s) {
  const auto control = [](char c) { return fmt::format("\\u{:04x}", static_cast<int>(c)); };
  return "\"" +
         escaped(s, {{'"', "\\\""}, {'\\', "\\\\"}, {'\n', "\\n"}, {'\t', "\\t"}}, +control) + "\"";
}

std::string jbox(const BoxRegion& b) {
  return fmt::format("[[{}, {}, {}], [{}, {}, {}]]", jnum(b.lo[0]), jnum(b.lo[1]), jnum(b.lo[2]),
                     jnum(b.hi[0]), jnum(b.hi[1]), jnum(b.hi[2]));
}

std::string jparams(const std::vector<ParamEstimate>& ps, const std::string& variant,
                    bool with_ci) {
  std::string s = "{";
  bool first = true;
  if (!variant.empty()) {
    s += "\"law\": " + jstr(variant);
    first = false;
  }
  for (const auto& p : ps) {
    if (!first) s += ", ";
    first = false;
    s += jstr(p.name) + ": {\"value\": " + jnum(p.value);
    if (with_ci)
      s += fmt::format(", \"ci95\": [{}, {}], \"ci95_at_bound\": [{}, {}]", jnum(p.ci_lo),
                       jnum(p.ci_hi), p.ci_at_bound_lo ? "true" : "false",
                       p.ci_at_bound_hi ? "true" : "false");
    if (with_ci && p.ci_time_step) s += ", \"ci95_from_time_step_error\": true";
    if (with_ci && p.ci_model_error) s += ", \"ci95_from_model_error\": true";
    if (with_ci && std::isfinite(p.ci_noise_lo))
      s += fmt::format(", \"ci95_noise_only\": [{}, {}]", jnum(p.ci_noise_lo), jnum(p.ci_noise_hi));
    if (with_ci && p.ci_scanned) s += ", \"ci95_spans_scan\": true";
    if (!p.unit.empty()) s += ", \"unit\": " + jstr(p.unit);
    s += "}";
  }
  return s + "}";
}

//! A JSON object written one key at a time.
struct JsonObject {
  std::string s = "{\n";
  void kv(const std::string& k, const std::string& v, bool last = false) {
    s += "  " + jstr(k) + ": " + v + (last ? "\n" : ",\n");
  }
};

//! report.json's verdict, parameters, regions, windows, markers and rms.
void json_result(JsonObject& j, const Diagnosis& d) {
  j.kv("verdict", jstr(d.verdict));
  j.kv("effect", d.effect.empty() ? "null" : jstr(d.effect));
  j.kv("effect_parameters",
       jparams(d.effect_parameters, d.effect == "material_law" ? d.variant : "", true));
  j.kv("effect_variant", d.variant.empty() ? "null" : jstr(d.variant));
  j.kv("baseline_parameters",
       fmt::format("{{\"youngs_modulus\": {}, \"poisson_ratio\": {}, \"density\": {}, "
                   "\"youngs_modulus_over_density\": {}, \"nominal_youngs_modulus\": {}, "
                   "\"nominal_poisson_ratio\": {}, \"poisson_ratio_held\": {}, "
                   "\"density_calibrated\": false}}",
                   jnum(d.youngs_modulus), jnum(d.poisson_ratio), jnum(d.density),
                   jnum(d.youngs_modulus / d.density), jnum(d.youngs_nominal),
                   jnum(d.poisson_nominal), d.poisson_held ? "true" : "false"));
  if (const ThinBody b = thin_body(d); b.thin)
    j.kv("thin_body", fmt::format("{{\"identified\": \"youngs_modulus * thickness^2 / density\", "
                                  "\"thickness\": {}, \"length\": {}, "
                                  "\"thickness_at_nominal_youngs_modulus\": {}}}",
                                  jnum(b.thickness), jnum(b.length), jnum(b.equivalent_thickness)));
  if (!d.release.empty())
    j.kv("release_state",
         fmt::format("{{\"preload_scale\": {}, \"time_offset\": {}, \"release_duration\": {}}}",
                     jnum(d.release[0].value), jnum(d.release[1].value), jnum(d.release[2].value)));
  j.kv("modes_hz",
       fmt::format("{{\"measured\": [{}, {}], \"fitted\": [{}, {}], "
                   "\"modal_damping_ratio\": [{}, {}]}}",
                   jnum(d.modes_measured[0]), jnum(d.modes_measured[1]), jnum(d.modes_fitted[0]),
                   jnum(d.modes_fitted[1]), jnum(d.modal_damping[0]), jnum(d.modal_damping[1])));
  j.kv("region", d.has_region ? jbox(d.region) : "null");
  j.kv("located_region", d.located ? jbox(d.located_region) : "null");
  std::string tw = "[";
  for (std::size_t i = 0; i < d.time_windows.size(); ++i)
    tw += fmt::format("{}[{}, {}]", i ? ", " : "", jnum(d.time_windows[i].first),
                      jnum(d.time_windows[i].second));
  j.kv("time_windows", tw + "]");
  std::string ph = "[";
  for (std::size_t i = 0; i < d.window_phase.size(); ++i)
    ph += (i ? ", " : "") + jstr(d.window_phase[i]);
  j.kv("time_window_phases", ph + "]");
  std::string mk = "[";
  for (std::size_t i = 0; i < d.markers.size(); ++i) mk += (i ? ", " : "") + jstr(d.markers[i]);
  j.kv("markers", mk + "]");
  j.kv("rms_nominal", jnum(d.rms_nominal));
  j.kv("rms_before", jnum(d.rms_before));
  j.kv("rms_after", jnum(d.rms_after));
  j.kv("heldout_rms_nominal", jnum(d.heldout_rms_nominal));
  j.kv("heldout_rms_before", jnum(d.heldout_rms_before));
  j.kv("heldout_rms_after", jnum(d.heldout_rms_after));
  j.kv("runner_up",
       d.runner_up.empty()
           ? "null"
           : fmt::format("{{\"effect\": {}, \"score\": {}, \"heldout_rms\": {}, "
                         "\"delta_bic\": {}, \"vuong_z\": {}, \"gap_over_unexplained\": {}}}",
                         jstr(d.runner_up), jnum(d.runner_up_heldout), jnum(d.runner_up_heldout),
                         jnum(d.runner_up_bic), jnum(d.vuong_z), jnum(d.runner_up_gap)));
}

//! report.json's noise, misfit tests and the checks of the model's own error.
void json_checks(JsonObject& j, const Diagnosis& d) {
  j.kv("noise_estimate", jnum(d.noise_position));
  j.kv("noise_estimate_recording", jnum(d.noise_recording_position));
  j.kv("noise_estimate_acceleration", jnum(d.noise_acceleration));
  j.kv("noise_estimate_fitted", jnum(d.noise_fitted_position));
  j.kv("noise_estimate_acceleration_fitted", jnum(d.noise_fitted_acceleration));
  j.kv("misfit_tests", fmt::format("{{\"chi2_per_dof\": {}, \"whiteness_p\": {}, \"lag1\": {}, "
                                   "\"misfit\": {}}}",
                                   jnum(d.chi2_red), jnum(d.whiteness_p), jnum(d.lag1),
                                   d.misfit ? "true" : "false"));
  j.kv("numerical_check",
       fmt::format("{{\"dt\": {}, \"dt_half_amplitude_change_in_noise_sd\": {}, "
                   "\"dt_half_late_difference_in_noise_sd\": {}, \"dt_halved\": {}}}",
                   jnum(d.dt), jnum(d.numerical_change), jnum(d.numerical_dispersion),
                   d.dt_halved ? "true" : "false"));
  {
    const TimeStepCheck& t = d.time_step;
    j.kv("time_step_check",
         !t.done ? "null"
                 : fmt::format("{{\"dt_half_late_difference_in_noise_sd\": {}, \"threshold\": {}, "
                               "\"depends_on_dt\": {}, \"chi2_time_step_error\": {}, "
                               "\"chi2_fit\": {}, \"runs\": {}}}",
                               jnum(t.dispersion), jnum(t.threshold), t.flagged ? "true" : "false",
                               jnum(t.chi2_error), jnum(t.chi2_fit), t.runs));
  }
  {
    const RefinementCheck& r = d.refinement;
    j.kv("discretisation_check",
         fmt::format("{{\"done\": {}, \"skipped\": {}, \"grid\": {}, \"voxel_size\": {}, "
                     "\"voxels\": {}, "
                     "\"channels\": {}, \"youngs_modulus_refitted\": {}, \"error_rms\": {}, "
                     "\"error_in_noise_sd\": {}, \"error_chi2_scored\": {}, \"upper_bound\": {}, "
                     "\"runs\": {}}}",
                     r.done ? "true" : "false", jstr(r.skipped),
                     jstr(r.coarse ? "2h (grid convergence index, Fs 3)" : "h/2 (Richardson)"),
                     jnum(r.voxel_size), r.voxels, r.channels, jnum(r.youngs_modulus), jnum(r.rms),
                     jnum(r.noise_sd), jnum(r.chi2), r.upper_bound ? "true" : "false", r.runs));
    j.kv("parameters_effective", model_error_dominates(d) ? "true" : "false");
  }
  {
    const IntervalBasis& ib = d.intervals;
    const RefinementCheck& f = ib.fit_refinement;
    j.kv(
        "intervals",
        fmt::format(
            "{{\"threshold_from\": {}, \"threshold_in_residual_variances\": {}, "
            "\"residual_variance\": {}, \"chi2_time_step_error\": {}, "
            "\"chi2_cells_error\": {}, \"fit_discretisation_check\": {}, "
            "\"scan_points\": {}, \"scan_runs\": {}, \"profile_step_runs\": {}, "
            "\"profile_steps_lowering\": {}, \"profile_probes_again\": {}}}",
            jstr(ib.from), jnum(ib.threshold), jnum(ib.s2), jnum(ib.chi2_time_step),
            jnum(ib.chi2_cells),
            !(f.done || !f.skipped.empty())
                ? std::string("null")
                : fmt::format("{{\"done\": {}, \"skipped\": {}, \"voxel_size\": {}, "
                              "\"youngs_modulus_refitted\": {}, \"error_rms\": {}, "
                              "\"error_in_noise_sd\": {}, \"error_chi2_fitted\": {}, "
                              "\"refit_linearised\": {}, \"runs\": {}}}",
                              f.done ? "true" : "false", jstr(f.skipped), jnum(f.voxel_size),
                              jnum(f.youngs_modulus), jnum(f.rms), jnum(f.noise_sd), jnum(f.chi2),
                              f.linearised ? "true" : "false", f.runs),
            ib.scan_points, ib.scan_runs, ib.profile_runs, ib.profile_lowered, ib.profile_refines));
  }
  {
    const MisfitBudget& b = d.budget;
    j.kv("misfit_budget",
         fmt::format("{{\"evaluated\": {}, \"heldout_chi2\": {}, \"noise_chi2\": {}, "
                     "\"noise_sd_residual\": {}, \"most_explainable\": {}, \"exhausted\": {}}}",
                     b.evaluated ? "true" : "false", jnum(b.scored_chi2), jnum(b.noise_chi2),
                     jnum(b.noise_sd), jnum(b.bound), b.exhausted ? "true" : "false"));
  }
}

//! report.json's signatures, candidates, contenders, provenance and cost.
void json_lists(JsonObject& j, const Diagnosis& d) {
  std::string sg = "[";
  for (std::size_t i = 0; i < d.signatures.size(); ++i)
    sg += fmt::format("{}{{\"name\": {}, \"present\": {}, \"value\": {}, \"detail\": {}}}",
                      i ? ", " : "", jstr(d.signatures[i].name),
                      d.signatures[i].present ? "true" : "false", jnum(d.signatures[i].value),
                      jstr(d.signatures[i].detail));
  j.kv("signatures", sg + "]");
  std::string cs = "[";
  for (std::size_t i = 0; i < d.candidates.size(); ++i) {
    const Candidate& c = d.candidates[i];
    cs += fmt::format(
        "{}\n    {{\"effect\": {}, \"variant\": {}, \"screen_chi2_drop\": {}, \"refitted\": {}",
        i ? "," : "", jstr(c.effect), c.variant.empty() ? "null" : jstr(c.variant),
        jnum(c.screen_gain), c.fitted ? "true" : "false");
    if (c.fitted)
      cs += fmt::format(
          ", \"parameters\": {}, \"chi2\": {}, \"k\": {}, \"lrt\": {}, "
          "\"delta_bic\": {}, \"rms\": {}, \"heldout_rms\": {}, \"passes\": {}, "
          "\"why\": {}",
          jparams(c.params, "", false), jnum(c.chi2), c.k, jnum(c.lrt), jnum(c.delta_bic),
          jnum(c.rms), jnum(c.heldout_rms), c.passes ? "true" : "false", jstr(c.why));
    cs += "}";
  }
  j.kv("candidates", cs + "]");
  std::string ct = "[";
  for (std::size_t i = 0; i < d.contenders.size(); ++i)
    ct += (i ? ", " : "") + jstr(d.contenders[i]);
  j.kv("contenders", ct + "]");
  j.kv("ambiguity_experiment",
       d.ambiguity_experiment.empty() ? "null" : jstr(d.ambiguity_experiment));
  j.kv("unexplained_misfit", d.unexplained.empty() ? "null" : jstr(d.unexplained));
  j.kv("deck", jstr(d.deck));
  j.kv("recording", jstr(d.recording));
  j.kv("forward_model", jstr(d.model));
  {
    std::string lo = "[";
    for (std::size_t i = 0; i < d.effects_left_out.size(); ++i)
      lo += fmt::format("{}{{\"effect\": {}, \"why\": {}}}", i ? ", " : "",
                        jstr(d.effects_left_out[i].first), jstr(d.effects_left_out[i].second));
    j.kv("effects_left_out", lo + "]");
  }
  {
    std::string dr = "[";
    for (std::size_t i = 0; i < d.deeper_refits.size(); ++i)
      dr += (i ? ", " : "") + jstr(d.deeper_refits[i]);
    j.kv("deeper_refits", dr + "]");
  }
  j.kv("polish", fmt::format("{{\"rounds\": {}, \"runs\": {}, \"chi2_before\": {}, "
                             "\"chi2_after\": {}, \"reason\": {}}}",
                             d.polish.rounds, d.polish.runs, jnum(d.polish.chi2_before),
                             jnum(d.polish.chi2_after), jstr(d.polish.reason)));
  std::string costs = "[";
  for (std::size_t i = 0; i < d.phases.size(); ++i)
    costs += fmt::format("{}{{\"phase\": {}, \"runs\": {}, \"wall_seconds\": {}}}", i ? ", " : "",
                         jstr(d.phases[i].name), d.phases[i].runs, jnum(d.phases[i].wall_seconds));
  j.kv(
      "cost",
      fmt::format("{{\"forward_runs\": {}, \"runs_reused\": {}, \"failed_runs\": {}, "
                  "\"first_failure\": {}, \"continued_runs\": {}, \"run_seconds\": {}, "
                  "\"idle_seconds\": {}, \"wall_seconds\": {}, \"ranks\": {}, \"phases\": {}]}}",
                  d.runs, d.runs_reused, d.failed_runs,
                  d.failed_runs > 0 ? jstr(d.first_failure) : std::string("null"), d.continued_runs,
                  jnum(d.run_seconds), jnum(d.idle_seconds), jnum(d.wall_seconds), d.ranks, costs),
      true);
}

std::string json(const Diagnosis& d) {
  JsonObject j;
  json_result(j, d);
  json_checks(j, d);
  json_lists(j, d);
  return j.s + "}\n";
}

//! report.md's verdict: the effect, its parameters and their intervals, or why none.
void markdown_verdict(std::ostringstream& m, const Diagnosis& d) {
  const char* cells = d.model == "mpm" ? "cells" : "voxels";
  m << "## Verdict\n\n";
  if (d.verdict == "none") {
    m << "**No missing physics.** After calibrating the baseline no effect of the library "
         "improves the fit to held-out data significantly.\n\n";
    if (!d.unexplained.empty()) m << "Note: " << d.unexplained << ".\n\n";
  } else if (d.effect.empty()) {
    m << "**Missing physics, not identified.** The recording departs from the calibrated deck "
         "by far more than the noise and the model's own voxels can, and no refitted effect of "
         "the library explains it.\n\n";
    if (!d.unexplained.empty())
      m << static_cast<char>(std::toupper(static_cast<unsigned char>(d.unexplained[0])))
        << d.unexplained.substr(1) << ".\n\n";
  } else {
    m << fmt::format("**{}: {}**{}.\n\n",
                     d.verdict == "ambiguous" ? "Ambiguous" : "Missing physics", d.effect,
                     d.variant.empty() ? "" : " (law " + d.variant + ")");
    if (!d.effect_parameters.empty()) {
      m << "| parameter | value | 95 % profile interval |\n|---|---|---|\n";
      for (const auto& p : d.effect_parameters)
        m << fmt::format("| {} | {:.4g} {} | [{:.4g}{}, {:.4g}{}] |\n", p.name, p.value, p.unit,
                         p.ci_lo, p.ci_at_bound_lo ? " (bound)" : "", p.ci_hi,
                         p.ci_at_bound_hi ? " (bound)" : "");
      m << "\n";
      const RefinementCheck& f = d.intervals.fit_refinement;
      if (model_error_dominates(d))
        m << fmt::format(
            "These values are effective ones of the model's {0}: the discretisation check "
            "puts the {0}' own error {1}{2:.3g} noise sd rms ({3:.3g} {5}), more than {4:g} "
            "times the noise. Finer {0} (domain.voxel_size) would measure them.\n\n",
            cells, d.refinement.upper_bound ? "at most " : "at ", d.refinement.noise_sd,
            d.refinement.rms, kEffectiveAboveNoise, value_unit(d));
      const IntervalBasis& ib = d.intervals;
      if (ib.from != "noise") {
        std::string parts;
        if (ib.chi2_time_step > 0)
          parts += fmt::format(
              "the time step's, chi-square {:.4g} (the fit rerun at dt/2, 4/3 of "
              "the difference{})",
              ib.chi2_time_step, d.time_step.flagged ? "" : ", its part along E left out");
        if (ib.chi2_cells > 0)
          parts += fmt::format(
              "{}the {}', chi-square {:.4g} (the fit rerun on {} of h/2, E "
              "refitted{}, {:.3g} noise sd rms)",
              parts.empty() ? "" : ", and ", cells, ib.chi2_cells, cells,
              f.linearised ? " by the linearisation of a pair of runs" : "", f.noise_sd);
        m << fmt::format(
            "The intervals include the model's own error on the fitted values: {}. A bias of "
            "the parameters can hide behind that much chi-square, so it is the intervals' "
            "threshold ({:.4g} residual variances instead of 3.84): parameter values closer "
            "than that cannot be told apart by this model. The noise alone would give the "
            "narrower `ci95_noise_only` of report.json, conditional on the model.\n\n",
            parts, ib.threshold);
      } else if (f.done) {
        m << fmt::format(
            "The selected fit rerun on {0} of h/2 (E refitted) differs by {1:.3g} noise sd "
            "rms (chi-square {2:.4g} on the fitted values), within the intervals' "
            "threshold.\n\n",
            cells, f.noise_sd, f.chi2);
      }
      if (!f.done && !f.skipped.empty())
        m << fmt::format(
            "The intervals do not include the model's {}' error: it was not measured for the "
            "selected fit ({}).\n\n",
            cells, f.skipped);
    }
    if (d.has_region)
      m << fmt::format("Region: [{:.4g}, {:.4g}, {:.4g}] to [{:.4g}, {:.4g}, {:.4g}] m.\n\n",
                       d.region.lo[0], d.region.lo[1], d.region.lo[2], d.region.hi[0],
                       d.region.hi[1], d.region.hi[2]);
    if (!d.ambiguity_experiment.empty()) m << d.ambiguity_experiment << "\n\n";
  }
}

//! report.md's fit: the rms of each model, the checks of the model's own error, the misfit.
void markdown_fit(std::ostringstream& m, const Diagnosis& d) {
  const bool mpm = d.model == "mpm";
  const char* cells = d.model == "mpm" ? "cells" : "voxels";
  const char* unit = value_unit(d);
  m << fmt::format("## Fit\n\n| | fitted data rms ({0}) | held-out rms ({0}) |\n|---|---|---|\n",
                   unit);
  m << fmt::format("| nominal deck | {:.4g} | {:.4g} |\n", d.rms_nominal, d.heldout_rms_nominal);
  m << fmt::format("| calibrated baseline | {:.4g} | {:.4g} |\n", d.rms_before,
                   d.heldout_rms_before);
  m << fmt::format("| with the selected effect | {:.4g} | {:.4g} |\n\n", d.rms_after,
                   d.heldout_rms_after);
  m << fmt::format(
      "Noise estimate: {:.3g} {} (local cubic fits over 7 samples, the lower of the recording's, "
      "{:.3g} {}, and the calibrated baseline's residual's). Calibrated E = {:.4g} Pa "
      "(deck {:.4g}), nu = {:.3f} (deck {:.3f}{}); density kept at {:g} kg/m^3, so E/rho = {:.4g} "
      "m^2/s^2 is what the data fix. These are effective values of the {}.\n\n",
      value_noise(d), unit,
      d.accelerations_only ? d.noise_recording_acceleration : d.noise_recording_position, unit,
      d.youngs_modulus, d.youngs_nominal, d.poisson_ratio, d.poisson_nominal,
      d.poisson_held ? ", held: --hold-poisson"
      : d.one_series ? "; one measured series sees no lateral contraction, so nu trades with E "
                       "here: --hold-poisson fits E alone"
                     : "",
      d.density, d.youngs_modulus / d.density,
      mpm ? "MPM model: a few cells to the thickness, whose particles' discretisation error E "
            "and nu absorb"
          : "voxel model: trilinear voxels a few to the thickness are stiffer in bending than "
            "the continuum, and E, nu absorb that");
  if (const ThinBody b = thin_body(d); b.thin) {
    const char* axis = "xyz";
    m << fmt::format(
        "The body is thin ({:.3g} m along {}, {:.3g} m along {}: {:.0f} to 1). Where its motion "
        "is bending, its frequencies fix E t^2/rho (t: the thickness), not E: this recording "
        "cannot tell E = {:.4g} Pa at the deck's t = {:.4g} m from the deck's E = {:.4g} Pa at "
        "t = {:.4g} m ({:+.1f} %), nor from a support that gives in rotation. A measured "
        "thickness, a static deflection under a known load or a sensor near the support "
        "separates them.\n\n",
        b.length, axis[b.long_axis], b.thickness, axis[b.thin_axis], b.length / b.thickness,
        d.youngs_modulus, b.thickness, d.youngs_nominal, b.equivalent_thickness,
        100 * (b.equivalent_thickness / b.thickness - 1));
  }
  if (!d.release.empty())
    m << fmt::format(
        "Release state (fitted with E and nu, then held): the pre-load is {:.4g} times the "
        "deck's, released over {:.3g} s, and the recording's t = 0 is the model's t = {:.4g} "
        "s.\n\n",
        d.release[0].value, d.release[2].value, d.release[1].value);
  if (d.modes_measured[0] > 0) {
    m << "| mode | measured (Hz) | fitted (Hz) | difference | modal damping ratio |\n"
         "|---|---|---|---|---|\n";
    for (std::size_t k = 0; k < 2; ++k)
      if (d.modes_measured[k] > 0)
        m << fmt::format("| {} | {:.4g} | {:.4g} | {:+.2f} % | {} |\n", k + 1, d.modes_measured[k],
                         d.modes_fitted[k], 100 * (d.modes_fitted[k] / d.modes_measured[k] - 1),
                         std::isnan(d.modal_damping[k])
                             ? std::string("-")
                             : fmt::format("{:.3g} %", 100 * d.modal_damping[k]));
    m << "\n";
  }
  if (std::isfinite(d.noise_fitted_position) || std::isfinite(d.noise_fitted_acceleration))
    m << fmt::format(
        "Noise on the fitted model's residual (the same local cubics): {}{}. The weights "
        "above were fixed before any effect was fitted; this is the better estimate where an "
        "effect was missing.\n\n",
        std::isfinite(d.noise_fitted_position) ? fmt::format("{:.3g} m", d.noise_fitted_position)
                                               : std::string(d.accelerations_only ? "" : "- m"),
        std::isfinite(d.noise_fitted_acceleration)
            ? fmt::format("{}accelerations {:.3g} m/s^2 (the weights': {:.3g})",
                          d.accelerations_only ? "" : ", ", d.noise_fitted_acceleration,
                          d.noise_acceleration)
            : std::string());
  m << fmt::format(
      "Numerical dissipation check: rerunning at dt/2 changes the late-time amplitude by {:.3g} "
      "noise sd ({}) and the late-time motion by {:.3g} noise "
      "sd (phase, absorbed by the calibrated E); dt = {:g} s{}.\n\n",
      d.numerical_change,
      mpm ? "explicit MPM substeps, fixed for every run" : "the trapezoidal rule adds no damping",
      d.numerical_dispersion, d.dt, d.dt_halved ? ", halved because of it" : "");
  if (d.time_step.done)
    m << fmt::format(
        "Time-step check of the selected fit: rerun at dt/2, its late-time motion moves by {:.3g} "
        "noise sd (the deck's: {:.3g}){}.\n\n",
        d.time_step.dispersion, d.numerical_dispersion,
        !d.time_step.flagged
            ? "; its parameters do not depend on the step"
            : fmt::format(
                  "; the fit depends on its time step. Its error (chi-square {:.4g}, 4/3 of the "
                  "dt-to-dt/2 difference, against the fit's {:.4g}) {}: "
                  "parameter values closer than that cannot be told apart at this step, so read "
                  "the intervals as what this recording and this step can tell, not as a "
                  "measurement. The chi-square is rough on that scale, so each interval also "
                  "spans a scan of the parameter's range ({} values, the others held at the "
                  "fit): the values within the threshold, widened to their neighbours",
                  d.time_step.chi2_error, d.time_step.chi2_fit,
                  d.intervals.from == "time_step_error"
                      ? "sets the intervals' threshold (above)"
                      : "is part of the intervals' threshold (above)",
                  d.intervals.scan_points));
  if (d.refinement.done && d.refinement.coarse)
    m << fmt::format(
        "Discretisation check: the calibrated baseline rerun on {0} of {1:g} m ({2} {0}, E "
        "at the h {0}' rest frequency, {3:.5g} Pa) puts the error of the model's own {0} "
        "at most {4:.3g} {7} rms ({5:.3g} noise sd; the whole h-to-2h difference: the two-grid "
        "convergence index with safety factor 3); every effect kept explains more held-out "
        "chi-square than that ({6:.4g}), so no h/2 run was needed.\n\n",
        cells, d.refinement.voxel_size, d.refinement.voxels, d.refinement.youngs_modulus,
        d.refinement.rms, d.refinement.noise_sd, d.refinement.chi2, unit);
  else if (d.refinement.done)
    m << fmt::format(
        "Discretisation check: the calibrated baseline rerun on {} of {:g} m ({} {}, E "
        "{} {:.5g} Pa) puts the error of the model's own {} {}{:.3g} {} rms ({:.3g} "
        "noise sd; 4/3 of the h-to-h/2 difference); an effect is kept only when it explains "
        "more held-out chi-square than that ({:.4g}){}.\n\n",
        cells, d.refinement.voxel_size, d.refinement.voxels, cells,
        d.refinement.upper_bound ? (mpm ? "as calibrated," : "at the h voxels' rest frequency,")
                                 : "refitted to",
        d.refinement.youngs_modulus, cells, d.refinement.upper_bound ? "at most " : "at ",
        d.refinement.rms, unit, d.refinement.noise_sd, d.refinement.chi2,
        d.refinement.upper_bound ? "; this bound already decides, so E was not refitted" : "");
  else if (!d.refinement.skipped.empty())
    m << "Discretisation check not done: " << d.refinement.skipped << ".\n\n";
  if (d.budget.evaluated)
    m << fmt::format(
        "Misfit budget: the calibrated baseline's held-out chi-square is {:.4g}, of which the "
        "noise accounts for about {:.4g} (sd {:.3g} {}, estimated on its residual); a missing "
        "effect could explain at most {:.4g} (the noise counted at half, with 3-sd margins){}."
        "\n\n",
        d.budget.scored_chi2, d.budget.noise_chi2, d.budget.noise_sd, unit, d.budget.bound,
        d.budget.exhausted
            ? fmt::format(", which is not more than the error of the model's own voxels ({:.4g}): "
                          "no effect could be kept, and none was refitted",
                          d.refinement.chi2)
        : d.refinement.done
            ? fmt::format(", more than the error of the model's own voxels ({}{:.4g}): the "
                          "effects were refitted",
                          d.refinement.upper_bound ? "at most " : "", d.refinement.chi2)
            : std::string());
  m << fmt::format(
      "Misfit of the calibrated baseline: chi2/dof = {:.3g}, residual whiteness p = {:.2g} "
      "(lag-1 autocorrelation {:.2f}) -> {}.\n\n",
      d.chi2_red, d.whiteness_p, d.lag1,
      d.misfit ? "something is not modelled" : "consistent with noise");
}

//! report.md's where and when: time windows, markers, the stiffness map, signatures.
void markdown_where(std::ostringstream& m, const Diagnosis& d) {
  m << "## Where and when\n\n";
  if (d.time_windows.empty())
    m << "No time window has residual variance above twice the noise.\n\n";
  for (std::size_t i = 0; i < d.time_windows.size(); ++i)
    m << fmt::format("- {:.3g} s to {:.3g} s ({})\n", d.time_windows[i].first,
                     d.time_windows[i].second, d.window_phase[i]);
  m << "\nMost affected markers: ";
  for (std::size_t i = 0; i < d.markers.size(); ++i) m << (i ? ", " : "") << d.markers[i];
  m << ".\n\n";
  if (d.located)
    m << fmt::format(
        "Stiffness sensitivity map: the residual points at [{:.4g}, {:.4g}, {:.4g}] to "
        "[{:.4g}, {:.4g}, {:.4g}] m (see sensitivity.png).\n\n",
        d.located_region.lo[0], d.located_region.lo[1], d.located_region.lo[2],
        d.located_region.hi[0], d.located_region.hi[1], d.located_region.hi[2]);
  m << "Signatures:\n\n";
  for (const auto& s : d.signatures)
    m << fmt::format("- {} {}: {}\n", s.present ? "[x]" : "[ ]", s.name, s.detail);
}

//! report.md's candidates, the rules, the cost.
void markdown_candidates(std::ostringstream& m, const Diagnosis& d) {
  m << fmt::format(
      "\n## Candidates\n\n| effect | screening chi2 drop | refit chi2 | dBIC | held-out rms "
      "({}) | selected by the rules |\n|---|---|---|---|---|---|\n",
      value_unit(d));
  for (const auto& c : d.candidates) {
    if (c.fitted)
      m << fmt::format("| {}{} | {:.4g} | {:.4g} | {:.1f} | {:.4g} | {} |\n", c.effect,
                       c.variant.empty() ? "" : ":" + c.variant, c.screen_gain, c.chi2, c.delta_bic,
                       c.heldout_rms, c.passes ? "passes" : "fails");
    else
      m << fmt::format("| {}{} | {:.4g} | not refitted | | | |\n", c.effect,
                       c.variant.empty() ? "" : ":" + c.variant, c.screen_gain);
  }
  m << "\nRules: an effect is kept when its likelihood-ratio statistic passes p < 0.001, its "
       "BIC improves by more than 10, and it lowers the noise-weighted held-out rms by at least "
       "20 %; the best kept effect has the lowest noise-weighted held-out chi-square; a second "
       "kept effect that Vuong's test on the held-out data cannot tell from it (z < 2, batch "
       "means over 10 samples), or whose held-out chi-square exceeds the winner's by less than "
       "the misfit the winner leaves beyond the noise (a difference below the model "
       "discrepancy both carry), makes the verdict ambiguous.";
  if (std::isfinite(d.vuong_z) && std::isfinite(d.runner_up_gap))
    m << fmt::format(" Here z = {:.2f} and the gap is {:.3g} x the unexplained misfit, against {}.",
                     d.vuong_z, d.runner_up_gap, d.runner_up);
  else if (std::isfinite(d.vuong_z))
    m << fmt::format(
        " Here z = {:.2f} against {}, and the winner leaves no misfit beyond the "
        "noise.",
        d.vuong_z, d.runner_up);
  if (!d.deeper_refits.empty()) {
    std::string names;
    for (const auto& n : d.deeper_refits) names += (names.empty() ? "" : ", ") + n;
    m << fmt::format(
        " The first refits left far more held-out misfit than the noise and the model's own "
        "cells account for (over {:g} times), so the next screened effects were refitted as "
        "well: {}.",
        kDeeperRefitFactor, names);
  }
  if (d.polish.rounds > 0)
    m << fmt::format(
        " The selected effect's refit stopped at its iteration limit still descending, so it was "
        "continued to its optimum ({} more fit(s), {} runs): chi-square {:.6g} -> {:.6g} on the "
        "fitted values{} ({}).",
        d.polish.rounds, d.polish.runs, d.polish.chi2_before, d.polish.chi2_after,
        d.polish.chi2_after < d.polish.chi2_before ? "" : ", not lowered", d.polish.reason);
  m << "\n\n";
  m << fmt::format(
      "Cost: {} forward runs ({} more asked for again and taken from the memo), {:.1f} s of "
      "runs, {:.1f} s wall on {} rank(s); the ranks spent {:.1f} s more in batches of runs "
      "waiting for one another's runs and exchanging results.\n\n",
      d.runs, d.runs_reused, d.run_seconds, d.wall_seconds, d.ranks, d.idle_seconds);
  if (d.failed_runs > 0)
    m << fmt::format(
        "{} of the forward runs failed (their parameters were rejected); the first: {}.\n\n",
        d.failed_runs, d.first_failure);
  if (d.continued_runs > 0)
    m << fmt::format(
        "{} of the forward runs compressed StVK voxels below the principal stretch {} (StVK "
        "softens there towards its compressive limit point; the stress was continued "
        "linearly).\n\n",
        d.continued_runs, kStvkContinuedStretch);
  if (!d.phases.empty()) {
    m << "| phase | forward runs | wall s |\n|---|---:|---:|\n";
    for (const auto& p : d.phases)
      m << fmt::format("| {} | {} | {:.1f} |\n", p.name, p.runs, p.wall_seconds);
    m << "\n";
  }
}

std::string markdown(const Diagnosis& d) {
  std::ostringstream m;
  m << "# gen4d diagnose\n\n";
  m << fmt::format("Deck `{}`, recording `{}`; forward model: {}.\n\n", d.deck, d.recording,
                   d.model == "mpm" ? "the MPM solver (particles on a grid)"
                                    : "the deck's voxels (hexahedra, trapezoidal rule)");
  if (!d.effects_left_out.empty()) {
    m << "Effects of the library this model does not represent, not tried:";
    for (const auto& [name, why] : d.effects_left_out) m << fmt::format(" {} ({});", name, why);
    m << "\n\n";
  }
  markdown_verdict(m, d);
  markdown_fit(m, d);
  markdown_where(m, d);
  markdown_candidates(m, d);
  m << "Plots: residual_time.png, marker_error.png, trajectories.png"
    << (d.located ? ", sensitivity.png" : "") << "; data: fit.csv.\n";
  return m.str();
}

std::string fit_csv(const Diagnosis& d, const Observations& obs) {
  std::string s = "channel,t,component,observed,baseline,fitted,heldout\n";
  const char* comp = "xyz";
  for (std::size_t i = 0; i < obs.size(); ++i)
    s += fmt::format("{},{:.9g},{},{:.9g},{:.9g},{:.9g},{}\n",
                     obs.ids[static_cast<std::size_t>(obs.channel[i])], obs.t[i],
                     comp[obs.component[i]], obs.y[i],
                     d.baseline_pred.ok ? d.baseline_pred.y[i] : std::nan(""),
                     d.fitted_pred.ok ? d.fitted_pred.y[i] : std::nan(""), obs.heldout[i] ? 1 : 0);
  return s;
}

//! The two axes along which the body is largest (the projection of the maps).
std::pair<int, int> map_axes(const BoxRegion& b) {
  int ax[3] = {0, 1, 2};
  std::sort(ax, ax + 3, [&](int x, int y) { return b.hi[x] - b.lo[x] > b.hi[y] - b.lo[y]; });
  return {std::min(ax[0], ax[1]), std::max(ax[0], ax[1])};
}

//! Adds the outline of box, projected on axes a, b, to m in colour rgb.
void outline(io::ScatterMap& m, const BoxRegion& box, int a, int b, io::Rgb rgb) {
  m.rects.push_back({box.lo[a], box.lo[b], box.hi[a], box.hi[b]});
  m.rect_colors.push_back(rgb);
}

//! A map of the body projected on axes a, b: titles and its outline.
io::ScatterMap body_map(const Diagnosis& d, int a, int b, std::string title,
                        std::string colorbar_label) {
  const char* axis_name = "XYZ";
  io::ScatterMap m;
  m.title = std::move(title);
  m.xlabel = std::string(1, axis_name[a]) + " (m)";
  m.ylabel = std::string(1, axis_name[b]) + " (m)";
  m.colorbar_label = std::move(colorbar_label);
  outline(m, d.body, a, b, {90, 90, 90});
  return m;
}

void plots(const std::string& dir, const Diagnosis& d, const Observations& obs) {
  {
    io::LineChart c;
    c.title = "Residual energy over time (1 = noise level)";
    c.xlabel = "t (s)";
    c.ylabel = "mean (residual / noise)^2";
    c.log_y = true;
    c.series.push_back({"calibrated baseline", d.bin_t, d.bin_e_before, io::palette_color(0)});
    c.series.push_back({d.effect.empty() ? "selected model (= baseline)" : "with " + d.effect,
                        d.bin_t, d.bin_e_after, io::palette_color(1)});
    c.series.push_back({"noise level",
                        {d.bin_t.front(), d.bin_t.back()},
                        {1.0, 1.0},
                        io::Rgb{120, 120, 120},
                        false,
                        1.0,
                        true});
    c.shaded_x = d.time_windows;
    io::write_line_chart(dir + "/residual_time.png", c);
  }
  {
    const auto [a, b] = map_axes(d.body);
    std::vector<io::ScatterMap> maps;
    for (int k = 0; k < 2; ++k) {
      io::ScatterMap& m = maps.emplace_back(body_map(
          d, a, b,
          k == 0 ? "Marker rms error, calibrated baseline" : "Marker rms error, selected model",
          fmt::format("rms ({})", value_unit(d))));
      for (std::size_t c = 0; c < d.channel_ids.size(); ++c) {
        m.x.push_back(d.channel_X[c][static_cast<std::size_t>(a)]);
        m.y.push_back(d.channel_X[c][static_cast<std::size_t>(b)]);
        m.value.push_back(k == 0 ? d.channel_rms_before[c] : d.channel_rms_after[c]);
        m.labels.push_back(d.channel_ids[c]);
      }
      if (d.has_region) outline(m, d.region, a, b, {220, 50, 50});
    }
    io::share_color_scale(maps);
    io::write_scatter_maps(dir + "/marker_error.png", maps, 2, 700, 420);
    if (d.located && !d.block_center.empty()) {
      io::ScatterMap m = body_map(
          d, a, b, "Stiffness sensitivity (share of chi2 one super-voxel explains)", "share");
      for (std::size_t i = 0; i < d.block_center.size(); ++i) {
        m.x.push_back(d.block_center[i][static_cast<std::size_t>(a)]);
        m.y.push_back(d.block_center[i][static_cast<std::size_t>(b)]);
        m.value.push_back(d.block_gain[i]);
      }
      outline(m, d.located_region, a, b, {220, 50, 50});
      io::write_scatter_maps(dir + "/sensitivity.png", {m}, 1, 900, 420);
    }
  }
  {
    std::vector<io::LineChart> charts;
    for (const std::string& id : d.markers) {
      const auto it = std::find(obs.ids.begin(), obs.ids.end(), id);
      const int c = static_cast<int>(it - obs.ids.begin());
      const int comp = main_component(obs, c);
      io::LineChart ch;
      ch.title =
          fmt::format("{} '{}', {}",
                      obs.requests[static_cast<std::size_t>(c)].acceleration ? "sensor" : "marker",
                      id, "xyz"[comp]);
      ch.xlabel = "t (s)";
      ch.ylabel = obs.requests[static_cast<std::size_t>(c)].acceleration ? "m/s^2" : "m";
      io::Series so{"observed", {}, {}, io::Rgb{40, 40, 40}, true, 1.0};
      io::Series sb{"calibrated baseline", {}, {}, io::palette_color(0)};
      io::Series sf{d.effect.empty() ? "selected model" : "with " + d.effect,
                    {},
                    {},
                    io::palette_color(1),
                    false,
                    1.5,
                    true};
      for (std::size_t i = 0; i < obs.size(); ++i)
        if (obs.channel[i] == c && obs.component[i] == comp) {
          so.x.push_back(obs.t[i]);
          so.y.push_back(obs.y[i]);
          sb.x.push_back(obs.t[i]);
          sb.y.push_back(d.baseline_pred.ok ? d.baseline_pred.y[i] : std::nan(""));
          sf.x.push_back(obs.t[i]);
          sf.y.push_back(d.fitted_pred.ok ? d.fitted_pred.y[i] : std::nan(""));
        }
      ch.series = {so, sb, sf};
      ch.shaded_x = d.time_windows;
      charts.push_back(std::move(ch));
    }
    if (!charts.empty()) io::write_chart_grid(dir + "/trajectories.png", charts, 1, 1000, 320);
  }
}

}  // namespace

void write_reports(const std::string& dir, const Diagnosis& d, const Observations& obs) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw RuntimeError("cannot create output folder " + dir + ": " + ec.message());
  io::write_text_atomically(dir + "/fit.csv", fit_csv(d, obs));
  plots(dir, d, obs);
  io::write_text_atomically(dir + "/report.md", markdown(d));
  // report.json last: its presence marks a complete diagnosis.
  io::write_text_atomically(dir + "/report.json", json(d));
}

}  // namespace gen4d::diagnose
