//! Stage select: per effect the variant to keep, the fits ranked (passing first, then by held-out
//! score), the winner continued to its optimum and checked against the model's own error at its
//! fit, Vuong's test and the gap against the runner-up, and the verdict: none, missing physics (an
//! effect, or none the library explains), or ambiguous with an experiment that separates the
//! contenders.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "core/Log.hpp"
#include "diagnose/Pipeline.hpp"
#include "diagnose/Tuning.hpp"

namespace gen4d::diagnose {

namespace {

//! Per effect the variant with the best BIC, unless a variant with fewer parameters fits the
//! held-out data as well (Vuong z < 2): extra parameters always absorb some model discrepancy, so
//! the simpler variant stands until the data need the larger one.
void choose_variants(State& s) {
  const Observations& obs = s.obs;
  std::vector<Candidate>& variant_fits = s.variant_fits;
  std::vector<std::string>& chosen = s.chosen;
  const std::vector<char>& scored = *s.scored;
  std::vector<Candidate>& fits = s.fits;
  for (const std::string& name : chosen) {
    const Candidate* b = nullptr;
    for (const Candidate& c : variant_fits)
      if (c.effect == name && (!b || c.delta_bic > b->delta_bic)) b = &c;
    if (!b) continue;
    const Candidate* simple = b;
    for (const Candidate& c : variant_fits) {
      if (c.effect != name || c.params.size() >= b->params.size() || !c.passes) continue;
      if (vuong_z(obs, scored, b->pred, c.pred) >= 2) continue;
      if (simple == b || c.params.size() < simple->params.size() ||
          (c.params.size() == simple->params.size() && score(s, c) < score(s, *simple)))
        simple = &c;
    }
    if (simple != b)
      log::info(
          "  {}: variant {} kept over {} (held-out fits equal within "
          "Vuong z < 2)",
          name, simple->variant, b->variant);
    fits.push_back(*simple);
  }
}

//! The fits ranked: passing first, failed fits last, then by score; best and second.
void rank_fits(State& s) {
  std::vector<Candidate>& fits = s.fits;
  std::vector<std::size_t>& order = s.order;
  const Candidate*& best = s.best;
  const Candidate*& second = s.second;
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    if (fits[a].passes != fits[b].passes) return fits[a].passes;
    if (fits[a].pred.ok != fits[b].pred.ok) return fits[a].pred.ok;  // failed fits last
    return score(s, fits[a]) < score(s, fits[b]);
  });
  best = !order.empty() && fits[order[0]].passes ? &fits[order[0]] : nullptr;
  second = order.size() > 1 ? &fits[order[1]]
                            : (best ? nullptr : (order.empty() ? nullptr : &fits[order[0]]));
}

//! The winner's fit to its optimum. A refit stops after opt.max_iterations, enough to rank the
//! effects; where the winner's stopped there still descending it is continued from its end
//! (kPolishRounds more fits at most) before it is checked, reported and its intervals drawn. The
//! polished fit is scored by the same rules (set_fit), and the ranking redone; each fit is
//! continued once at most.
void polish_best(State& s) {
  Evaluator& ev = *s.ev;
  const DiagnoseOptions& opt = s.opt;
  std::vector<Candidate>& fits = s.fits;
  std::vector<std::size_t>& order = s.order;
  const Candidate*& best = s.best;
  std::vector<char>& polished = s.polished;
  bool continued = false;
  while (best && !polished[order[0]]) {
    const std::size_t i = order[0];
    polished[i] = 1;
    Candidate& c = fits[i];
    FitContinuation& P = c.polish;
    P.chi2_before = P.chi2_after = c.chi2;
    for (int round = 0; round < kPolishRounds && c.fit_at_limit; ++round) {
      const LsqProblem pr = effect_problem(s, find_effect(c.effect), c.variant);
      const double before = c.chi2;
      log::info("  {} {}: its refit stopped at the iteration limit ({}); continued", c.effect,
                c.variant, c.fit_reason);
      const LsqResult r = least_squares(ev, pr, c.z, opt.max_iterations, false);
      ++P.rounds;
      P.runs += r.runs;
      P.reason = r.reason;
      continued = true;
      if (!r.pred.ok || !(r.chi2 < before)) break;
      set_fit(s, c, r);
      P.chi2_after = c.chi2;
      log::info("  {} {} continued: chi2 {:.6g} -> {:.6g}; {}", c.effect, c.variant, before, c.chi2,
                c.why);
    }
    rank_fits(s);
  }
  if (continued) s.phase_done("the selected fit continued");
}

//! Whether the fit's own discretisation check can matter: not where the baseline's check (a bound,
//! on the scored values) already puts the model's error below the noise's threshold.
bool fit_check_pays(const State& s, const Candidate& c) {
  const Diagnosis& D = s.D;
  const double N = s.N;
  const double s2_fit = c.chi2 / std::max(1.0, N - static_cast<double>(c.z.size()));
  return !D.refinement.done || D.refinement.noise_sd * D.refinement.noise_sd * N > 3.84 * s2_fit;
}

//! The winner's gain against the model's own error at its fit: the selected fit rerun on cells of
//! h/2, E refitted there. Where that error, on the fitted values, is not less than what the effect
//! gained over the calibrated deck there, the gain cannot be told from the error of the model at
//! the fitted parameters, and the effect is not kept; the next kept effect is then checked the same
//! way.
void fit_check(State& s) {
  const Observations& obs = s.obs;
  Diagnosis& D = s.D;
  const double t_free = s.t_free;
  const double chi2_0 = s.chi2_0;
  const DiagnoseOptions& opt = s.opt;
  const std::vector<std::array<double, 3>>& channel_X = s.channel_X;
  const Config& cfg = s.cfg;
  MPI_Comm comm = s.comm;
  std::vector<Candidate>& fits = s.fits;
  std::vector<std::size_t>& order = s.order;
  const Candidate*& best = s.best;
  while (best && !best->params.empty() && opt.refinement_check && fit_check_pays(s, *best)) {
    const Physics p_fit =
        effect_problem(s, find_effect(best->effect), best->variant).physics(best->z);
    D.intervals.fit_refinement = refinement_check(comm, cfg, obs, channel_X, p_fit, best->pred,
                                                  obs.train, t_free, 0.0, true);
    const RefinementCheck& F = D.intervals.fit_refinement;
    log::info(
        "the {} fit's own discretisation error (h/2 rerun, E refitted to "
        "{:.5g} Pa): "
        "{}",
        best->effect, F.youngs_modulus,
        F.done ? fmt::format("{:.3g} m rms ({:.3g} noise sd), chi2 {:.4g} on the fitted "
                             "values ({} runs)",
                             F.rms, F.noise_sd, F.chi2, F.runs)
               : "not measured: " + F.skipped);
    s.phase_done("fit's discretisation check (h/2 reruns)");
    D.phases.back().runs = F.runs;  // the fine model's runs (ev counts none)
    const double gain = chi2_0 - best->chi2;
    if (!F.done || F.chi2 < gain) break;
    Candidate& b = fits[order[0]];
    b.passes = false;
    b.why += fmt::format(
        "; gains {:.4g} of chi2 on the fitted values, not "
        "more than the model's own error at "
        "this fit ({:.4g}, h/2 rerun of the fit)",
        gain, F.chi2);
    log::info("  {} {} not kept: {}", b.effect, b.variant, b.why);
    D.intervals.fit_refinement = RefinementCheck{};
    rank_fits(s);
    polish_best(s);
  }
}

//! How far a contender's held-out fit is behind the winner's, in units of the misfit the winner
//! itself leaves beyond the noise (held-out chi2 - its count): below 1, the two differ by less than
//! the model discrepancy both carry, and the data cannot attribute the difference to physics.
//! Infinite when the winner fits to the noise (Vuong's test decides).
double contender_gap(const State& s, const Candidate& c) {
  const std::vector<char>& scored = *s.scored;
  const Candidate* best = s.best;
  const double n_scored = static_cast<double>(std::count(scored.begin(), scored.end(), 1));
  const double unexplained = score(s, *best) - n_scored;
  return unexplained > 0 ? (score(s, c) - score(s, *best)) / unexplained
                         : std::numeric_limits<double>::infinity();
}

//! Vuong's test between the two best kept effects (the verdict is ambiguous below z = 2), and the
//! runner-up's scores.
void runner_up(State& s) {
  const Observations& obs = s.obs;
  Diagnosis& D = s.D;
  const bool has_holdout = s.has_holdout;
  const std::vector<char>& scored = *s.scored;
  const Candidate*& best = s.best;
  const Candidate*& second = s.second;
  if (best && second && second->passes) {
    D.vuong_z = vuong_z(obs, scored, best->pred, second->pred);
    D.runner_up_gap = contender_gap(s, *second);
    log::info(
        "  {} vs {}: Vuong z = {:.2f}; held-out chi2 gap {:.3g} x the "
        "winner's unexplained misfit "
        "(ambiguous when z < 2 or the gap < 1)",
        best->effect, second->effect, D.vuong_z, D.runner_up_gap);
  }
  if (second) {
    D.runner_up = second->effect + (second->variant.empty() ? "" : ":" + second->variant);
    D.runner_up_heldout = has_holdout ? second->heldout_rms : second->rms;
    D.runner_up_bic = second->delta_bic;
  }
}

//! The verdict from the winner, or without one: missing physics only where the noise and the
//! voxels' own error cannot make the misfit (the discretisation check decides, on voxels of 2h
//! where their bound suffices), else none; the fitted model's residual noise.
void verdict(State& s) {
  const Observations& obs = s.obs;
  Diagnosis& D = s.D;
  const LsqResult& base = s.base;
  const Physics& calibrated = s.calibrated;
  const Candidate*& best = s.best;
  D.rms_after = D.rms_before;
  D.heldout_rms_after = D.heldout_rms_before;
  D.fitted_pred = base.pred;
  if (!best) {
    D.verdict = "none";
    // "No missing physics" only where the noise and the voxels' own error could make the misfit:
    // else it is physics outside the library, or an effect the screening ranked too low to refit.
    // The discretisation check decides, on voxels of 2h where their bound suffices. The budget
    // counts the noise at half its estimated variance, an upper bound of what an effect could
    // explain; a claim that something is missing takes the lower bound as well, the misfit beyond
    // the noise at its full estimated variance and 3 sd of its spread: on a calibrated deck that
    // fits to the noise (a null case on fine enough voxels) the budget's other half is noise.
    const double beyond_noise =
        D.budget.scored_chi2 - D.budget.noise_chi2 - 3 * std::sqrt(2 * D.budget.noise_chi2);
    const double decide = std::min(D.budget.bound, beyond_noise) / kUnidentifiedFactor;
    const bool at_noise = D.misfit && !D.budget.exhausted && beyond_noise <= 0;
    if (D.misfit && !D.budget.exhausted && !at_noise && s.has_holdout && s.opt.refinement_check) {
      if (!D.refinement.done || (D.refinement.upper_bound && D.refinement.chi2 >= decide)) {
        D.refinement = refinement_check(s.comm, s.cfg, obs, s.channel_X, calibrated, base.pred,
                                        (*s.scored), s.t_free, decide);
        check_phase_done(s);
      }
      if (D.refinement.done && D.refinement.chi2 < decide) D.verdict = "missing_physics";
    }
    if (D.verdict == "missing_physics")
      D.unexplained = fmt::format(
          "the calibrated deck leaves chi2/dof {:.3g} and residual whiteness p "
          "= {:.2g}; of its "
          "held-out misfit ({:.4g}, the noise's share {:.4g}) an effect could "
          "explain {:.4g}, "
          "over {:g} times the error of the model's own voxels ({:.4g}{}). No "
          "effect of the "
          "library that was refitted explains it (see the candidates): the "
          "physics is outside "
          "the library, or an effect the screening ranked too low to refit "
          "(rerun with "
          "--effects to refit the ones the signatures suggest)",
          D.chi2_red, D.whiteness_p, D.budget.scored_chi2, D.budget.noise_chi2, D.budget.bound,
          kUnidentifiedFactor, D.refinement.chi2,
          D.refinement.coarse ? ", at most: the h-to-2h bound" : "");
    else if (D.misfit && D.budget.exhausted)
      D.unexplained = fmt::format(
          "the calibrated deck leaves chi2/dof {:.3g} and residual "
          "whiteness p = {:.2g}, but its "
          "held-out misfit ({:.4g}) is the noise ({:.4g} at the "
          "residual's noise) and the error "
          "of the model's own voxels ({:.4g}): a missing effect "
          "could explain at most {:.4g}, "
          "no more than that error, so none was refitted",
          D.chi2_red, D.whiteness_p, D.budget.scored_chi2, D.budget.noise_chi2, D.refinement.chi2,
          D.budget.bound);
    else if (at_noise)
      D.unexplained = fmt::format(
          "the calibrated deck leaves chi2/dof {:.3g} and residual whiteness p = {:.2g}, but its "
          "held-out misfit ({:.4g}) is within the noise's share ({:.4g} at the residual's noise, "
          "3 sd {:.3g}), and no effect of the library improves the held-out fit significantly",
          D.chi2_red, D.whiteness_p, D.budget.scored_chi2, D.budget.noise_chi2,
          3 * std::sqrt(2 * D.budget.noise_chi2));
    else if (D.misfit)
      D.unexplained = fmt::format(
          "the calibrated deck leaves chi2/dof {:.3g} and residual whiteness p "
          "= {:.2g}, but no "
          "effect of the library improves the held-out fit significantly: the "
          "remaining misfit is "
          "model discrepancy (discretisation) or physics outside the library",
          D.chi2_red, D.whiteness_p);
  } else {
    D.verdict = "missing_physics";
    D.effect = best->effect;
    D.variant = best->variant;
    D.effect_parameters = best->params;
    D.polish = best->polish;
    D.rms_after = best->rms;
    D.heldout_rms_after = best->heldout_rms;
    D.fitted_pred = best->pred;
    D.youngs_modulus = best->youngs_modulus;
    D.poisson_ratio = best->poisson_ratio;
    // The release state as the effect's fit moved it (its trailing parameters).
    const std::size_t nr = s.release_specs.size();
    if (nr > 0 && best->z.size() == 2 + best->params.size() + nr)
      for (std::size_t j = 0; j < nr; ++j)
        D.release[j].value = from_z(s.release_specs[j], best->z[best->z.size() - nr + j]);
    if (D.effect == "heterogeneity") D.has_region = true, D.region = s.ctx.region;
  }
  if (D.fitted_pred.ok) {
    residual_noise(obs, D.fitted_pred, D.noise_fitted_position, D.noise_fitted_acceleration);
    log::info("noise on the fitted model's residual: {:.3g} m{}", D.noise_fitted_position,
              std::isfinite(D.noise_fitted_acceleration)
                  ? fmt::format(", {:.3g} m/s^2", D.noise_fitted_acceleration)
                  : std::string());
  }
}

//! Ambiguous when the runner-up also passes and either Vuong's test on the held-out data cannot
//! tell it from the winner (z < 2) or its gap is below the winner's unexplained misfit: when the
//! winner itself leaves model discrepancy beyond the noise, a smaller difference between two
//! effects says which one absorbs that discrepancy best, not which is the physics. The experiment
//! proposed: the two fitted models rerun under changed test conditions (load or density halved or
//! doubled), the one where they differ most.
void ambiguity(State& s) {
  const Observations& obs = s.obs;
  Diagnosis& D = s.D;
  Evaluator& ev = *s.ev;
  const std::vector<char>& scored = *s.scored;
  std::vector<Candidate>& fits = s.fits;
  std::vector<std::size_t>& order = s.order;
  const Candidate*& best = s.best;
  const Candidate*& second = s.second;
  if (!best) return;
  if (second && second->passes && (D.vuong_z < 2 || D.runner_up_gap < 1)) {
    D.contenders = {best->effect, second->effect};
    // Any further kept effect just as close to the winner is a contender too.
    for (std::size_t k = 2; k < order.size(); ++k) {
      const Candidate& c = fits[order[k]];
      if (!c.passes) continue;
      const double z = vuong_z(obs, scored, best->pred, c.pred);
      if (contender_gap(s, c) < 1 || z < 2) D.contenders.push_back(c.effect);
    }
    D.verdict = "ambiguous";
    // An experiment that separates them: the two fitted models rerun under changed test conditions,
    // the one where they differ most proposed. A changed load separates effects that depend on
    // amplitude (plasticity, a nonlinear law); a specimen of another density (same shape) separates
    // forces on the mass from forces on the surface (mass damping and linear air drag both damp
    // each bending mode of a uniform beam as c / (2 m omega) and differ only in how they scale with
    // the mass per length).
    const Effect& e1 = find_effect(best->effect);
    const Effect& e2 = find_effect(second->effect);
    struct Trial {
      bool load;  // else the density
      double factor;
      const char* what;
    };
    const Trial trials[4] = {
        {true, 0.5, "load"}, {true, 2.0, "load"}, {false, 0.5, "density"}, {false, 2.0, "density"}};
    std::vector<Physics> batch_x;
    for (const Trial& tr : trials)
      for (int k = 0; k < 2; ++k) {
        const Candidate& c = k ? *second : *best;
        Physics p = effect_problem(s, k ? e2 : e1, c.variant).physics(c.z);
        (tr.load ? p.load_scale : p.density) *= tr.factor;
        batch_x.push_back(p);
      }
    const auto pr = ev.run(batch_x);
    double diff[4] = {0, 0, 0, 0}, diff_m[4] = {0, 0, 0, 0};  // noise sd rms, m rms
    for (int s = 0; s < 4; ++s) {
      if (!pr[2 * s].ok || !pr[2 * s + 1].ok) continue;
      double acc = 0, acc_m = 0, n_m = 0;
      for (std::size_t i = 0; i < obs.size(); ++i) {
        const double d = pr[2 * s].y[i] - pr[2 * s + 1].y[i];
        acc += std::pow(d / obs.sigma[i], 2);
        if (!obs.requests[static_cast<std::size_t>(obs.channel[i])].acceleration)
          acc_m += d * d, n_m += 1;
      }
      diff[s] = std::sqrt(acc / static_cast<double>(obs.size()));
      diff_m[s] = n_m > 0 ? std::sqrt(acc_m / n_m) : std::nan("");
    }
    const int s = static_cast<int>(std::max_element(diff, diff + 4) - diff);
    std::string others;
    for (int k = 0; k < 4; ++k)
      if (k != s)
        others += fmt::format("{}{} x{:g}: {:.2g}", others.empty() ? "" : ", ", trials[k].what,
                              trials[k].factor, diff[k]);
    D.ambiguity_experiment = fmt::format(
        "{} and {} fit equally well. Repeat the test {}: the two fitted models "
        "then differ by "
        "{:.3g} noise sd rms ({:.3g} m rms at the markers; chi-square {:.4g} "
        "over this "
        "recording's {} values); other changes tried, in noise sd rms: {}.",
        best->effect, second->effect,
        trials[s].load ? fmt::format("with the applied load scaled by {:g}", trials[s].factor)
                       : fmt::format("on a specimen of the same shape with "
                                     "{:g} times the density (another "
                                     "material, or distributed mass added)",
                                     trials[s].factor),
        diff[s], diff_m[s], diff[s] * diff[s] * static_cast<double>(obs.size()), obs.size(),
        others);
  }
}

}  // namespace

void select(State& s) {
  choose_variants(s);
  s.order.resize(s.fits.size());
  std::iota(s.order.begin(), s.order.end(), 0);
  s.polished.assign(s.fits.size(), 0);
  rank_fits(s);
  polish_best(s);
  fit_check(s);
  runner_up(s);
  verdict(s);
  ambiguity(s);
  s.phase_done("selection");
}

}  // namespace gen4d::diagnose
