//! Stage screen: every applicable effect's probes (small values of its parameters, in groups) run
//! at the calibrated baseline, their residual directions projected off the baseline's and fitted
//! jointly by linear least squares: the linearised chi-square drop of each (effect, variant) ranks
//! the candidates and gives each refit its start.
#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>

#include "core/Log.hpp"
#include "diagnose/Pipeline.hpp"

namespace gen4d::diagnose {

LsqProblem effect_problem(State& s, const Effect& e, const std::string& variant) {
  const LsqProblem& pb = s.pb;
  const EffectContext& ctx = s.ctx;
  const auto specs = e.params(ctx, variant);
  LsqProblem pr;
  // (log E, nu) from the baseline's problem, whose release state (if any) goes to the tail.
  pr.lo.assign(pb.lo.begin(), pb.lo.begin() + 2);
  pr.hi.assign(pb.hi.begin(), pb.hi.begin() + 2);
  pr.step.assign(pb.step.begin(), pb.step.begin() + 2);
  for (const auto& sp : specs) {
    pr.lo.push_back(to_z(sp, sp.lo));
    pr.hi.push_back(to_z(sp, sp.hi));
    pr.step.push_back(sp.log ? 1e-2 : 1e-2 * (to_z(sp, sp.hi) - to_z(sp, sp.lo)) / 10);
  }
  pr.physics = [&e, &ctx, &s, specs, variant](const std::vector<double>& z) {
    Physics p = base_physics(s, z);
    apply_release(s, z, 2 + specs.size(), p);
    std::vector<double> nat;
    for (std::size_t q = 0; q < specs.size(); ++q) nat.push_back(from_z(specs[q], z[2 + q]));
    e.apply(variant, nat, ctx, p);
    return p;
  };
  add_release(s, pr);
  pr.mask = &s.obs.train;
  return pr;
}

namespace {

//! A probe: an effect variant at parameter values p, in a group of its probes, at a baseline.
struct Probe {
  const Effect* effect;
  std::string variant;
  std::size_t group;
  std::vector<double> p;
  std::size_t baseline = 0;  //!< 0: the calibrated baseline, else bases[baseline]
};

//! The probes of every applicable effect of the library; `bases` gets the baselines they ask for
//! after the calibrated one. An effect may ask for probes at other baselines too
//! (Effect::probe_baselines): their groups follow the calibrated baseline's, numbered on, and the
//! best group counts.
std::vector<Probe> build_probes(State& s, std::vector<Physics>& bases) {
  const EffectContext& ctx = s.ctx;
  const ForwardModel& model = *s.model;
  std::vector<Probe> probes;
  for (const Effect* e : s.library) {
    if (!e->applicable(ctx)) continue;
    for (const auto& var : e->variants(ctx)) {
      if (!model.models(e->name(), var)) continue;
      const auto groups = e->probe_groups(ctx, var);
      std::size_t group = 0;
      for (const auto& g : groups) {
        for (const auto& p : g) probes.push_back({e, var, group, p});
        ++group;
      }
      for (const Physics& b : e->probe_baselines(ctx, var)) {
        bases.push_back(b);
        for (const auto& g : groups) {
          for (const auto& p : g) probes.push_back({e, var, group, p, bases.size() - 1});
          ++group;
        }
      }
    }
  }
  return probes;
}

//! The linearised chi-square drop of the group of probes [i, j) (least squares of r0 on their
//! projected directions) and the start it points a scalable effect to.
double group_gain(State& s, const std::vector<Probe>& probes,
                  const std::vector<Prediction>& probe_preds, std::size_t i, std::size_t j,
                  std::vector<double>& start, std::vector<std::vector<double>>& subset_starts) {
  const Observations& obs = s.obs;
  const EffectContext& ctx = s.ctx;
  const Eigen::VectorXd& r0 = s.base.r;
  // Group [i, j): least squares of r0 on the projected probe directions.
  const Eigen::Index g = static_cast<Eigen::Index>(j - i);
  Eigen::MatrixXd Dm(r0.size(), g);
  bool ok = true;
  for (std::size_t k = i; k < j; ++k) {
    ok = ok && probe_preds[k].ok;
    Dm.col(static_cast<Eigen::Index>(k - i)) =
        project(s, weighted_residual(obs, probe_preds[k], obs.train) - r0);
  }
  double gain = 0;
  start = probes[i].p;
  if (ok) {
    // Probe directions the recording barely responds to (pivots under 1e-3 of the largest:
    // gravity's normal component on a block sliding on a frictionless floor) are left out of the
    // combination: a coefficient fitted on them extrapolates far past what the probe measured (gz
    // at +11.5 m/s^2, the block afloat, as the refit's start).
    Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(Dm);
    qr.setThreshold(1e-3);
    const Eigen::VectorXd c = qr.solve(-r0);
    gain = r0.squaredNorm() - (r0 + Dm * c).squaredNorm();
    const Effect* e = probes[i].effect;
    if (e->scalable()) {
      const auto nul = e->null_values(ctx, probes[i].variant);
      start = nul;
      for (std::size_t k = i; k < j; ++k)
        for (std::size_t q = 0; q < nul.size(); ++q)
          start[q] +=
              std::max(0.0, c[static_cast<Eigen::Index>(k - i)]) * (probes[k].p[q] - nul[q]);
      // A group whose signs all fall out keeps the probe magnitudes.
      if (start == nul) start = probes[i].p;
      if (e->name() == "gravity") {  // signed: any direction
        for (std::size_t q = 0; q < nul.size(); ++q) {
          start[q] = nul[q];
          for (std::size_t k = i; k < j; ++k)
            start[q] += c[static_cast<Eigen::Index>(k - i)] * (probes[k].p[q] - nul[q]);
        }
        // The same least squares on every other subset of the probe directions: a component the
        // recording barely responds to linearly takes up what the others' linearisation misses
        // (a sag of a fifth of the length shortens the bar quadratically, which the axial
        // component mimics: gx at its 30 m/s^2 bound with gz at -9.2 where the truth is gz alone,
        // and the refit stuck there). Their runs decide the start (subset_start).
        const Eigen::Index g_all = (Eigen::Index{1} << g) - 1;
        for (Eigen::Index m = 1; m < g_all && g <= 4; ++m) {
          std::vector<Eigen::Index> cols;
          for (Eigen::Index k = 0; k < g; ++k)
            if (m & (Eigen::Index{1} << k)) cols.push_back(k);
          Eigen::MatrixXd Ds(r0.size(), static_cast<Eigen::Index>(cols.size()));
          for (std::size_t k = 0; k < cols.size(); ++k)
            Ds.col(static_cast<Eigen::Index>(k)) = Dm.col(cols[k]);
          Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qs(Ds);
          qs.setThreshold(1e-3);
          const Eigen::VectorXd cs = qs.solve(-r0);
          std::vector<double> alt = nul;
          for (std::size_t k = 0; k < cols.size(); ++k)
            for (std::size_t q = 0; q < nul.size(); ++q)
              alt[q] += cs[static_cast<Eigen::Index>(k)] *
                        (probes[i + static_cast<std::size_t>(cols[k])].p[q] - nul[q]);
          subset_starts.push_back(alt);
        }
      }
    }
  }
  return gain;
}

//! A gravity start from its probes' linear fit on each subset of their directions (group_gain),
//! the full set's included: the one whose run fits the training data best, clamped to the
//! parameters' bounds. The linear fit extrapolates a 1 m/s^2 probe to a missing 9.81; where the
//! motion is not linear in it over that range, the full set's start can lie far from the truth.
std::vector<double> subset_start(State& s, const Effect& e, const std::string& variant,
                                 const Physics& baseline, std::vector<std::vector<double>> starts) {
  const auto specs = e.params(s.ctx, variant);
  std::vector<Physics> batch;
  for (auto& st : starts) {
    for (std::size_t q = 0; q < specs.size(); ++q)
      st[q] = std::clamp(st[q], specs[q].lo, specs[q].hi);
    Physics ph = baseline;
    e.apply(variant, st, s.ctx, ph);
    batch.push_back(ph);
  }
  const auto preds = s.ev->run(batch);
  std::size_t pick = 0;
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < preds.size(); ++k) {
    const double x = preds[k].ok ? weighted_residual(s.obs, preds[k], s.obs.train).squaredNorm()
                                 : std::numeric_limits<double>::infinity();
    if (x < best) best = x, pick = k;
  }
  if (pick != 0)
    log::info(
        "  screen {}: start [{:.4g} {:.4g} {:.4g}] (chi2 {:.4g}) from a subset of its probes' "
        "directions, over the full linear fit's [{:.4g} {:.4g} {:.4g}]",
        e.name(), starts[pick][0], starts[pick][1], starts[pick][2], best, starts[0][0],
        starts[0][1], starts[0][2]);
  return starts[pick];
}

}  // namespace

void screen(State& s) {
  const EffectContext& ctx = s.ctx;
  std::vector<Physics> bases = {s.calibrated};
  const std::vector<Probe> probes = build_probes(s, bases);
  std::vector<Physics> batch;
  for (const Probe& p : probes) {
    Physics ph = bases[p.baseline];
    p.effect->apply(p.variant, p.p, ctx, ph);
    batch.push_back(ph);
  }
  const auto probe_preds = s.ev->run(batch);
  std::vector<Candidate>& screened = s.screened;
  for (std::size_t i = 0; i < probes.size();) {
    std::size_t j = i;
    while (j < probes.size() && probes[j].effect == probes[i].effect &&
           probes[j].variant == probes[i].variant && probes[j].group == probes[i].group)
      ++j;
    std::vector<double> start;
    std::vector<std::vector<double>> subset_starts;
    const double gain = group_gain(s, probes, probe_preds, i, j, start, subset_starts);
    // Keep the best group per (effect, variant).
    auto it = std::find_if(screened.begin(), screened.end(), [&](const Candidate& c) {
      return c.effect == probes[i].effect->name() && c.variant == probes[i].variant;
    });
    if (it == screened.end()) {
      Candidate c;
      c.effect = probes[i].effect->name();
      c.variant = probes[i].variant;
      c.screen_gain = -1;
      screened.push_back(c);
      it = screened.end() - 1;
    }
    if (gain > it->screen_gain) {
      if (!subset_starts.empty()) {
        subset_starts.insert(subset_starts.begin(), start);
        start = subset_start(s, *probes[i].effect, probes[i].variant, bases[probes[i].baseline],
                             subset_starts);
      }
      it->screen_gain = gain;
      it->z.clear();
      it->base_start.clear();
      if (probes[i].baseline != 0) {
        const Physics& b = bases[probes[i].baseline];
        it->base_start = {std::log(b.youngs_modulus), b.poisson_ratio};
      }
      const auto specs = probes[i].effect->params(ctx, probes[i].variant);
      for (std::size_t q = 0; q < specs.size(); ++q)
        it->z.push_back(to_z(specs[q], std::clamp(start[q], specs[q].lo, specs[q].hi)));
    }
    i = j;
  }
  std::sort(screened.begin(), screened.end(),
            [](const Candidate& a, const Candidate& b) { return a.screen_gain > b.screen_gain; });
  for (const auto& c : screened)
    log::info("  screen {:<16} {:<12} linearised chi2 drop {:.4g} ({:.1f} %)", c.effect, c.variant,
              c.screen_gain, 100 * c.screen_gain / s.chi2_0);
  s.phase_done("screening");
}

}  // namespace gen4d::diagnose
