//! Stage refit: the best few screened effects (every variant of them) fitted jointly with the
//! baseline and scored on held-out data; the misfit budget and the model's own discretisation error
//! decide whether refits can matter and which gains are kept; where the best refit leaves far more
//! misfit than the noise and the cells, the next screened effects too.
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

double score(const State& s, const Candidate& c) {
  return s.has_holdout ? c.heldout_chi2 : c.chi2;
}

void set_fit(State& s, Candidate& c, const LsqResult& r) {
  const Observations& obs = s.obs;
  Diagnosis& D = s.D;
  EffectContext& ctx = s.ctx;
  const double chi2_0 = s.chi2_0;
  const double N = s.N;
  const bool has_holdout = s.has_holdout;
  const double score0 = s.score0;
  const double lnN = s.lnN;
  const Effect& e = find_effect(c.effect);
  const auto specs = e.params(ctx, c.variant);
  c.params.clear();
  c.fit_reason = r.reason;
  c.fit_at_limit = r.at_limit;
  c.fitted = true;
  c.z = r.z;
  c.chi2 = r.chi2;
  c.k = static_cast<int>(specs.size()) + e.discrete_dof();
  c.lrt = N * std::log(chi2_0 / std::max(r.chi2, 1e-300));
  c.delta_bic = c.lrt - c.k * lnN;
  c.rms = rms(obs, r.pred, obs.train);
  c.heldout_rms = rms(obs, r.pred, obs.heldout);
  c.youngs_modulus = std::exp(r.z[0]);
  c.poisson_ratio = r.z[1];
  c.pred = r.pred;
  c.J = r.J;
  for (std::size_t q = 0; q < specs.size(); ++q) {
    ParamEstimate pe;
    pe.name = specs[q].name;
    pe.unit = specs[q].unit;
    pe.value = from_z(specs[q], r.z[2 + q]);
    c.params.push_back(pe);
  }
  c.heldout_chi2 = weighted_residual(obs, r.pred, obs.heldout).squaredNorm();
  // The held-out gain is that of the noise-weighted rms (markers and accelerometers alike).
  const double h0 = has_holdout ? D.heldout_rms_before : D.rms_before;
  const double h1 = has_holdout ? c.heldout_rms : c.rms;
  const double gain = std::sqrt(score(s, c) / score0) - 1;
  const bool lrt_ok = c.lrt > chi2_crit999(std::max(1, c.k));
  const bool bic_ok = c.delta_bic > 10;
  const bool held_ok = gain <= -kMinHeldoutGain;
  c.passes = lrt_ok && bic_ok && held_ok;
  c.why = fmt::format(
      "LRT {:.1f} vs {:.1f} (p<0.001: {}), dBIC {:.1f} (>10: {}), held-out rms "
      "{:.3g} vs {:.3g}, weighted {:+.1f} % (needs <= -{:g} %: {})",
      c.lrt, chi2_crit999(std::max(1, c.k)), lrt_ok ? "yes" : "no", c.delta_bic,
      bic_ok ? "yes" : "no", h1, h0, 100 * gain, 100 * kMinHeldoutGain, held_ok ? "yes" : "no");
  if (r.abandoned) {  // an unconverged fit: its parameters mean nothing, it is
                      // not kept
    c.passes = false;
    c.why += fmt::format(
        "; fit given up after {} iterations (chi2 above {:g}x a passing fit's "
        "and not halving, "
        "or above {:g}x and at its rate still there at the iteration limit)",
        r.iterations, kAbandonFactor, kCompeteFactor);
  }
  if (!r.pred.ok) {
    // Every run of the fit failed (an explicit MPM stiffness damping past its stable beta): its
    // chi-square is the failure's penalty (100 noise sd a value), which can undercut a misfit of
    // hundreds of noise sd; it is not a fit, and not kept.
    c.passes = false;
    c.why += "; every run of its fit failed: " + r.pred.failure;
  }
}

void check_phase_done(State& s) {
  s.phase_done("discretisation check (2h, h/2 reruns)");
  s.D.phases.back().runs = s.D.refinement.runs;  // the fine model's runs (ev counts none)
}

namespace {

//! Refit order: by screening rank, slow effects last (a passing fit's chi-square then bars them
//! early when they cannot compete), and within an effect fewer parameters first.
std::tuple<bool, long, std::size_t> rank_of(const State& s, std::size_t i) {
  const std::vector<Candidate>& screened = s.screened;
  const std::vector<std::string>& chosen = s.chosen;
  const auto it = std::find(chosen.begin(), chosen.end(), screened[i].effect);
  return std::make_tuple(find_effect(screened[i].effect).slow(), it - chosen.begin(),
                         screened[i].z.size());
}

//! Up to opt.refit effects not in `skip`, by their best screened variant (positive gain).
std::vector<std::string> next_effects(const State& s, const std::vector<std::string>& skip) {
  std::vector<std::string> out;
  for (const Candidate& c : s.screened)
    if (c.screen_gain > 0 && static_cast<int>(out.size()) < s.opt.refit &&
        std::find(skip.begin(), skip.end(), c.effect) == skip.end() &&
        std::find(out.begin(), out.end(), c.effect) == out.end())
      out.push_back(c.effect);
  return out;
}

//! The screened variants (positive gain) of `effects`, as indices into s.screened, in refit
//! order (rank_of).
std::vector<std::size_t> refit_order(const State& s, const std::vector<std::string>& effects) {
  std::vector<std::size_t> out;
  for (std::size_t i = 0; i < s.screened.size(); ++i)
    if (s.screened[i].screen_gain > 0 &&
        std::find(effects.begin(), effects.end(), s.screened[i].effect) != effects.end())
      out.push_back(i);
  std::stable_sort(out.begin(), out.end(),
                   [&](std::size_t a, std::size_t b) { return rank_of(s, a) < rank_of(s, b); });
  return out;
}

//! A passing fit that explains no more held-out chi-square than the discretisation check's error
//! (D.refinement) is not kept.
void keep_above_discretisation(State& s, Candidate& c) {
  Diagnosis& D = s.D;
  if (!c.passes) return;
  const double explained = s.score0 - score(s, c);
  if (explained > D.refinement.chi2) return;
  c.passes = false;
  c.why += fmt::format(
      "; explains {:.4g} of held-out chi2, not more than the "
      "discretisation error "
      "({:.4g}, h/2 rerun)",
      explained, D.refinement.chi2);
  log::info("  {} {} not kept: {}", c.effect, c.variant, c.why);
}

//! The effects refitted (the best few by their best variant, every variant of them) and their
//! order; how candidates are scored.
void plan_refits(State& s) {
  const Observations& obs = s.obs;
  const LsqResult& base = s.base;
  const double chi2_0 = s.chi2_0;
  const double N = s.N;
  std::vector<std::string>& chosen = s.chosen;
  std::vector<std::size_t>& todo = s.todo;
  s.lnN = std::log(std::max(N, 2.0));
  // The best few effects (by their best variant) are refitted, every variant of them; BIC then
  // picks the variant. Linearised screening cannot rank variants: a stiffness-proportional damping
  // probe at the calibrated E looks worse than a mass-proportional one although the refit may fit
  // better. Variants with fewer parameters go first, and a variant that contains them (Rayleigh
  // contains mass and stiffness) starts from the best of their optima, so it can only improve on
  // them.
  chosen = next_effects(s, {});
  todo = refit_order(s, chosen);
  // Candidates are scored by their noise-weighted held-out chi-square (the training one when
  // nothing is held out), which weighs markers and accelerometers by their noise.
  s.has_holdout = obs.size() > static_cast<std::size_t>(s.ntrain);
  s.scored = s.has_holdout ? &obs.heldout : &obs.train;  // what score() sums
  s.score0 = s.has_holdout ? weighted_residual(obs, base.pred, obs.heldout).squaredNorm() : chi2_0;
}

//! The misfit budget: when the noise carries much of the baseline's held-out misfit, the
//! discretisation check is run now. If what a missing effect could explain at most (the misfit less
//! the noise's share) is not more than the error of the model's own voxels, no effect could be kept
//! whatever its refit, and none is refitted.
void misfit_budget_check(State& s) {
  const Observations& obs = s.obs;
  Diagnosis& D = s.D;
  const LsqResult& base = s.base;
  const std::vector<char>& scored = *s.scored;
  for (const Channel& ch : s.rec.channels) s.channel_X.push_back(ch.X);
  D.budget = misfit_budget(obs, base.pred, scored);
  // The bound holds for values the fits do not see; fitted ones an effect can overfit.
  D.budget.evaluated = D.budget.evaluated && s.has_holdout;
  if (s.opt.refinement_check && D.budget.evaluated) {
    D.refinement = refinement_check(s.comm, s.cfg, obs, s.channel_X, s.calibrated, base.pred,
                                    scored, s.t_free, D.budget.bound);
    D.budget.exhausted =
        D.refinement.done && !D.refinement.upper_bound && D.refinement.chi2 >= D.budget.bound;
    log::info(
        "misfit budget: held-out chi2 {:.4g}, noise share {:.4g} (noise "
        "{:.3g} m from the "
        "residual); an effect could explain at most {:.4g}{}",
        D.budget.scored_chi2, D.budget.noise_chi2, D.budget.noise_sd, D.budget.bound,
        D.budget.exhausted ? fmt::format(", not more than the discretisation error "
                                         "({:.4g}): nothing to refit",
                                         D.refinement.chi2)
                           : std::string());
    check_phase_done(s);
  }
}

//! A stiffness map concentrated in one box is evidence for heterogeneity however the generic probe
//! ranks: that probe softens the box the linearised map found, which is often smaller than the true
//! region, and other effects (gravity, plasticity) absorb a soft region as extra sag. Heterogeneity
//! is then refitted too (its region refined by forward runs), unless a refitted effect already
//! removes most of the held-out misfit.
void heterogeneity_too(State& s) {
  const std::vector<Candidate>& screened = s.screened;
  std::vector<std::string>& chosen = s.chosen;
  double best_gain = 0;
  for (const Candidate& c : s.variant_fits)
    best_gain = std::max(best_gain, 1 - std::sqrt(score(s, c) / s.score0));
  if (!s.D.budget.exhausted && s.region_share >= kRegionRefitShare &&
      best_gain < kRegionRefitBelowGain &&
      std::find(chosen.begin(), chosen.end(), "heterogeneity") == chosen.end()) {
    for (std::size_t i = 0; i < screened.size(); ++i)
      if (screened[i].effect == "heterogeneity" && screened[i].screen_gain > 0) {
        if (std::find(chosen.begin(), chosen.end(), "heterogeneity") == chosen.end()) {
          chosen.push_back("heterogeneity");
          log::info(
              "  heterogeneity refitted as well: the stiffness map's box "
              "explains {:.1f} % of "
              "chi2 (>= {:g} %) and the best refit lowers the held-out "
              "rms by {:.1f} % (< {:g} %)",
              100 * s.region_share, 100 * kRegionRefitShare, 100 * best_gain,
              100 * kRegionRefitBelowGain);
        }
        refit_one(s, i);
      }
  }
}

//! The model's own spatial discretisation error (the spatial twin of the dt/2 rerun), measured only
//! when an effect would be kept: the calibrated baseline rerun on voxels of h/2, E refitted to the
//! h run, the rest scaled by 4/3 (second order). An effect whose held-out gain is below it may be
//! absorbing the discretisation error rather than modelling physics, and is not kept. A check done
//! for the budget is reused when it decides the same.
void discretisation_gate(State& s) {
  const Observations& obs = s.obs;
  Diagnosis& D = s.D;
  const double t_free = s.t_free;
  const LsqResult& base = s.base;
  const DiagnoseOptions& opt = s.opt;
  std::vector<Candidate>& variant_fits = s.variant_fits;
  const std::vector<char>& scored = *s.scored;
  const double score0 = s.score0;
  const std::vector<std::array<double, 3>>& channel_X = s.channel_X;
  const Config& cfg = s.cfg;
  MPI_Comm comm = s.comm;
  const Physics& calibrated = s.calibrated;
  if (opt.refinement_check && std::any_of(variant_fits.begin(), variant_fits.end(),
                                          [](const Candidate& c) { return c.passes; })) {
    double least_explained = std::numeric_limits<double>::infinity();
    for (const Candidate& c : variant_fits)
      if (c.passes) least_explained = std::min(least_explained, score0 - score(s, c));
    const bool reuse =
        D.refinement.done && (!D.refinement.upper_bound || D.refinement.chi2 < least_explained);
    if (!reuse)
      D.refinement = refinement_check(comm, cfg, obs, channel_X, calibrated, base.pred, scored,
                                      t_free, least_explained);
    if (D.refinement.done)
      for (Candidate& c : variant_fits) keep_above_discretisation(s, c);
    if (!reuse) check_phase_done(s);
  } else if (!D.refinement.done && D.refinement.skipped.empty()) {
    D.refinement.skipped = opt.refinement_check ? "not needed: no effect passed the other rules"
                                                : "switched off (--no-refinement-check)";
  }
}

//! Deeper refits. Linearised screening ranks effects by a small probe at the calibrated deck; where
//! the missing effect is large, many effects explain most of that first step alike, and the
//! refitted few need not hold the one that fits. When the best passing refit leaves far more
//! held-out misfit than the noise and the model's own cells account for, the next screened effects
//! (as many as --refit) are refitted as well, under the same rules.
void deeper_refits(State& s) {
  Diagnosis& D = s.D;
  std::vector<Candidate>& variant_fits = s.variant_fits;
  std::vector<std::string>& chosen = s.chosen;
  if (D.refinement.done && s.has_holdout) {
    double best_score = std::numeric_limits<double>::infinity();
    for (const Candidate& c : variant_fits)
      if (c.passes) best_score = std::min(best_score, score(s, c));
    double n_scored = 0;
    for (char m : (*s.scored)) n_scored += m ? 1 : 0;
    const double accounted = n_scored + D.refinement.chi2;
    std::vector<std::string> more;
    if (std::isfinite(best_score) && best_score > kDeeperRefitFactor * accounted)
      more = next_effects(s, chosen);
    if (!more.empty()) {
      std::string names;
      for (const auto& m : more) names += (names.empty() ? "" : ", ") + m;
      log::info(
          "  the best refit leaves held-out chi2 {:.4g}, over {:g} x "
          "what the noise and the cells "
          "account for ({:.4g}): refitting the next s.screened effects as "
          "well: {}",
          best_score, kDeeperRefitFactor, accounted, names);
      D.deeper_refits = more;
      chosen.insert(chosen.end(), more.begin(), more.end());
      const std::size_t first_new = variant_fits.size();
      for (std::size_t i : refit_order(s, more)) refit_one(s, i);
      for (std::size_t k = first_new; k < variant_fits.size(); ++k)
        keep_above_discretisation(s, variant_fits[k]);
    }
  }
}

}  // namespace

void refit(State& s) {
  plan_refits(s);
  misfit_budget_check(s);
  if (!s.D.budget.exhausted)
    for (std::size_t i : s.todo) refit_one(s, i);
  heterogeneity_too(s);
  discretisation_gate(s);
  deeper_refits(s);
}

}  // namespace gen4d::diagnose
