//! Stage refit, one candidate's refit: its problem and start (the screening start, a nested
//! variant's optimum, a shrunk step; for an effect that moves a frequency, RefitStarts.cpp), its
//! fit (hypotheses, the race winner, or one fit; a heterogeneity box refined) and its scores.
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <tuple>

#include "core/Log.hpp"
#include "diagnose/RefitWork.hpp"
#include "diagnose/Tuning.hpp"

namespace gen4d::diagnose {

namespace {

//! screened[i]'s problem, its bars from the passing fits so far, and its screening start (from the
//! baseline its best screening group ran at: the calibrated one, or one the effect asked for, a law
//! swapped in at the deck's nu).
RefitWork prepare(State& s, std::size_t i) {
  EffectContext& ctx = s.ctx;
  const LsqResult& base = s.base;
  const std::vector<Candidate>& screened = s.screened;
  std::vector<Candidate>& variant_fits = s.variant_fits;
  RefitWork w;
  w.c = screened[i];
  const Candidate& c = w.c;
  w.e = &find_effect(c.effect);
  const Effect& e = *w.e;
  w.specs = e.params(ctx, c.variant);
  const auto& specs = w.specs;
  w.pr = effect_problem(s, e, c.variant);
  LsqProblem& pr = w.pr;
  w.nulls = e.null_values(ctx, c.variant);
  const auto& nulls = w.nulls;
  w.z_null = specs.empty() || nulls.empty() ? 0.0 : to_z(specs[0], nulls[0]);
  // Give up a fit that cannot compete: its chi-square stays above ten times that of a fit that
  // already passes (it could be neither the verdict nor an ambiguous contender).
  for (const Candidate& f : variant_fits)
    if (f.passes) {
      pr.abandon_chi2 = std::min(pr.abandon_chi2, kAbandonFactor * f.chi2);
      w.compete = std::min(w.compete, kCompeteFactor * f.chi2);
    }
  // From the baseline its best screening group ran at (the calibrated one, or one the effect asked
  // for: a law swapped in at the deck's nu).
  w.z0 = c.base_start.empty() ? base.z : c.base_start;
  w.z0.insert(w.z0.end(), c.z.begin(), c.z.end());
  w.grid = e.frequency_grid(ctx, c.variant);
  return w;
}

//! A variant that contains a fitted one (Rayleigh contains mass and stiffness damping) starts from
//! the best of their optima: shared parameters from it, the others at a tenth of their value in
//! another fitted variant (small, but with a gradient in log coordinates), else at the screening
//! start. False when no fitted variant is nested in it.
bool nested_start(State& s, RefitWork& w) {
  Candidate& c = w.c;
  const std::vector<ParamSpec>& specs = w.specs;
  std::vector<double>& z0 = w.z0;
  std::vector<Candidate>& variant_fits = s.variant_fits;
  const Candidate* nest = nullptr;  // the best fitted variant nested in this one
  for (const Candidate& f : variant_fits) {
    if (f.effect != c.effect || f.params.size() >= specs.size()) continue;
    bool nested = true;
    for (const auto& pe : f.params)
      nested = nested && std::any_of(specs.begin(), specs.end(),
                                     [&](const ParamSpec& sp) { return sp.name == pe.name; });
    if (nested && (!nest || f.chi2 < nest->chi2)) nest = &f;
  }
  if (nest) {
    z0[0] = nest->z[0];
    z0[1] = nest->z[1];
    for (std::size_t q = 0; q < specs.size(); ++q) {
      // Shared parameters from the nested optimum; the others at a tenth of their value in another
      // fitted variant (small, but with a gradient in log coordinates), else at the screening
      // start.
      double v = std::nan("");
      for (const auto& pe : nest->params)
        if (pe.name == specs[q].name) v = pe.value;
      if (std::isnan(v))
        for (const Candidate& f : variant_fits)
          if (f.effect == c.effect)
            for (const auto& pe : f.params)
              if (pe.name == specs[q].name) v = 0.1 * pe.value;
      if (!std::isnan(v)) z0[2 + q] = to_z(specs[q], std::clamp(v, specs[q].lo, specs[q].hi));
    }
  }
  return nest != nullptr;
}

//! A scalable effect starts where its probes' linear combination points; where that extrapolates
//! past what the probes measured (a direction with no response), the start fits worse than the
//! calibrated baseline. Then the effect's step from its null value is shrunk (1/2, 1/4, 1/8, run
//! together) and the best start taken. The start's run is the fit's first (memo).
void shrink_start(State& s, RefitWork& w) {
  const Observations& obs = s.obs;
  Evaluator& ev = *s.ev;
  const LsqResult& base = s.base;
  Candidate& c = w.c;
  const std::vector<ParamSpec>& specs = w.specs;
  LsqProblem& pr = w.pr;
  std::vector<double>& z0 = w.z0;
  const std::vector<double>& nulls = w.nulls;
  const double chi2_start =
      weighted_residual(obs, ev.run_one(pr.physics(z0)), *pr.mask).squaredNorm();
  if (chi2_start < base.chi2) return;
  std::vector<std::vector<double>> zs;
  std::vector<Physics> tries;
  for (const double f : {0.5, 0.25, 0.125}) {
    std::vector<double> z = z0;
    for (std::size_t q = 0; q < specs.size() && q < nulls.size(); ++q) {
      const double zn = to_z(specs[q], std::clamp(nulls[q], specs[q].lo, specs[q].hi));
      z[2 + q] = zn + f * (z0[2 + q] - zn);
    }
    zs.push_back(z);
    tries.push_back(pr.physics(z));
  }
  const auto got = ev.run(tries);
  double best = chi2_start;
  std::size_t pick = zs.size();
  for (std::size_t k = 0; k < got.size(); ++k) {
    const double x = weighted_residual(obs, got[k], *pr.mask).squaredNorm();
    if (got[k].ok && x < best) best = x, pick = k;
  }
  log::info(
      "  {} {}: the screening start fits worse than the baseline (chi2 {:.4g} "
      "vs "
      "{:.4g}); {}",
      c.effect, c.variant, chi2_start, base.chi2,
      pick < zs.size() ? fmt::format("starting at {} of its step (chi2 {:.4g})",
                                     std::array<const char*, 3>{"1/2", "1/4", "1/8"}[pick], best)
                       : std::string("no shorter step fits better, kept"));
  if (pick < zs.size()) z0 = zs[pick];
}

//! The candidate's fit from its start: each hypothesis briefly (its box refined), the better fitted
//! in full; the race winner through the face moves; otherwise one fit, by continuation in time for
//! an effect that moves a frequency (once), a heterogeneity box then refined.
LsqResult fit(State& s, RefitWork& w) {
  const Observations& obs = s.obs;
  EffectContext& ctx = s.ctx;
  Evaluator& ev = *s.ev;
  const std::vector<double>& windows = s.windows;
  const DiagnoseOptions& opt = s.opt;
  Candidate& c = w.c;
  const std::vector<ParamSpec>& specs = w.specs;
  LsqProblem& pr = w.pr;
  std::vector<double>& z0 = w.z0;
  std::vector<Hypothesis>& hypotheses = w.hypotheses;
  bool& continued = w.continued;
  const bool moves_frequency = !w.grid.empty();
  const double compete = w.compete;
  LsqResult r;
  if (!hypotheses.empty()) {
    double best = 1e300;
    BoxRegion best_box = ctx.region;
    for (std::size_t q = 0; q < hypotheses.size(); ++q) {
      const Hypothesis& hy = hypotheses[q];
      ctx.region = hy.region;
      log::info(
          "  {} hypothesis {}: E {:.4g} Pa, nu {:.3g}, {} {:.4g} in "
          "[{:.3g} {:.3g} "
          "{:.3g}]-[{:.3g} "
          "{:.3g} {:.3g}] (chi2 {:.4g})",
          c.effect, q + 1, std::exp(hy.z[0]), hy.z[1], specs[0].name, from_z(specs[0], hy.z[2]),
          hy.region.lo[0], hy.region.lo[1], hy.region.lo[2], hy.region.hi[0], hy.region.hi[1],
          hy.region.hi[2], hy.start_chi2);
      LsqResult rh = least_squares(ev, pr, hy.z, kRegionStartIterations, false);
      if (c.effect == "heterogeneity" && !rh.abandoned) refine_box(s, w, rh);
      log::info(
          "  {} hypothesis {}: chi2 {:.4g} in [{:.3g} {:.3g} "
          "{:.3g}]-[{:.3g} {:.3g} {:.3g}]",
          c.effect, q + 1, rh.chi2, ctx.region.lo[0], ctx.region.lo[1], ctx.region.lo[2],
          ctx.region.hi[0], ctx.region.hi[1], ctx.region.hi[2]);
      if (rh.pred.ok && rh.chi2 < best) best = rh.chi2, best_box = ctx.region, r = rh;
    }
    ctx.region = best_box;
    if (!r.z.empty()) r = least_squares(ev, pr, r.z, opt.max_iterations, false);
  }
  if (r.z.empty() && continued && c.effect == "heterogeneity") {
    // The race's winner, already fitted through the continuation windows and scored on the whole
    // recording (its run is in the memo), goes straight to the face moves, whose final fit is on
    // the whole recording: a fit of the whole recording before the moves gains little that the
    // moves' own Gauss-Newton step does not take.
    r.pred = ev.run_one(pr.physics(z0));
    if (r.pred.ok) {
      r.z = z0;
      r.r = weighted_residual(obs, r.pred, obs.train);
      r.chi2 = r.r.squaredNorm();
      refine_box(s, w, r);
      r = least_squares(ev, pr, r.z, opt.max_iterations, false);
    }
  }
  if (r.z.empty()) {
    if (!moves_frequency) pr.compete_chi2 = compete;  // its one fit (kCompeteFactor)
    r = moves_frequency && !continued
            ? continuation_fit(ev, pr, z0, windows, kWindowIterations, opt.max_iterations, false)
            : least_squares(ev, pr, z0, opt.max_iterations, false);
    if (c.effect == "heterogeneity" && !r.abandoned) {
      refine_box(s, w, r);
      r = least_squares(ev, pr, r.z, opt.max_iterations, false);
    }
  }
  return r;
}

}  // namespace

void refit_one(State& s, std::size_t i) {
  RefitWork w = prepare(s, i);
  const Effect& e = *w.e;
  const bool nest = nested_start(s, w);
  if (e.scalable() && !nest && w.grid.empty()) shrink_start(s, w);
  // Effects that move a frequency are fitted by continuation in time (continuation_fit), once: by
  // their region short fits, else by their refit.
  if (!w.grid.empty()) frequency_starts(s, w);
  const LsqResult r = fit(s, w);
  Candidate& c = w.c;
  const EffectContext& ctx = s.ctx;
  if (c.effect == "heterogeneity" && !r.abandoned) {
    log::info(
        "  heterogeneity region refined to [{:.3g} {:.3g} "
        "{:.3g}]-[{:.3g} {:.3g} {:.3g}]",
        ctx.region.lo[0], ctx.region.lo[1], ctx.region.lo[2], ctx.region.hi[0], ctx.region.hi[1],
        ctx.region.hi[2]);
    s.D.located_region = ctx.region;
  }
  set_fit(s, c, r);
  log::info("  refit {:<16} {:<12} chi2 {:.4g} -> {:.4g}; {}", c.effect, c.variant, s.chi2_0,
            c.chi2, c.why);
  s.phase_done(fmt::format("refit {}{}{}", c.effect, c.variant.empty() ? "" : " ", c.variant));
  s.variant_fits.push_back(std::move(c));
}

}  // namespace gen4d::diagnose
