//! Stage check: the selected fit's own time step (a dt/2 rerun compared late in the record) and
//! profile-likelihood intervals of its effect's parameters (the others re-optimised), at a
//! threshold set by the noise or by the model's own error (time step, cells) where larger.
#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>

#include "core/Log.hpp"
#include "diagnose/Profile.hpp"
#include "diagnose/Tuning.hpp"

namespace gen4d::diagnose {

namespace {

//! The selected fit's own time step (see TimeStepCheck): rerun at dt/2 and compared late in the
//! record as the numerical check compares the deck's. Where it moved by far more, the fit's
//! parameters depend on the step: what separates two parameter values is then their chi-square
//! difference against the step's own, 4/3 of the dt-to-dt/2 difference (second order), and
//! chi-square is rough on that scale (scans). Either way the step's error is part of the model's
//! own error that bounds the intervals.
void time_step_check(State& s) {
  const Observations& obs = s.obs;
  Diagnosis& D = s.D;
  Evaluator& ev = *s.ev;
  const Recording& rec = s.rec;
  const Candidate* best = s.best;
  if (!best || best->params.empty()) return;
  TimeStepCheck& T = D.time_step;
  Physics p_half = effect_problem(s, find_effect(best->effect), best->variant).physics(best->z);
  p_half.dt /= 2;
  s.half_fit = ev.run_one(p_half);
  const Prediction& half = s.half_fit;
  const double t_late = rec.t_begin() + 0.75 * (rec.t_end() - rec.t_begin());
  double dtrain = 0;
  for (std::size_t i = 0; i < obs.size() && half.ok; ++i)
    if (obs.train[i]) {
      const double r = (best->pred.y[i] - half.y[i]) / obs.sigma[i];
      dtrain += r * r;
    }
  T.done = true;
  T.runs = 1;
  T.dispersion = half.ok ? late_difference(obs, best->pred, half, t_late)
                         : std::numeric_limits<double>::infinity();
  T.threshold = std::max(kTimeStepFlag * D.numerical_dispersion, 1.0);
  T.flagged = T.dispersion > T.threshold;
  T.chi2_fit = best->chi2;
  T.chi2_error =
      half.ok ? std::pow(4.0 / 3.0, 2) * dtrain : std::numeric_limits<double>::infinity();
  log::info(
      "time-step check of the {} fit (dt/2 rerun): late-time difference "
      "{:.3g} noise sd (the "
      "deck's: {:.3g}; the parameters depend on dt above {:.3g}){}",
      best->effect, T.dispersion, D.numerical_dispersion, T.threshold,
      T.flagged ? fmt::format(": the step's error, chi2 {:.4g} against "
                              "the fit's {:.4g}, sets "
                              "the intervals",
                              T.chi2_error, T.chi2_fit)
                : std::string());
}

//! The fit's Jacobian (its own where it ended on one, else np runs), the threshold in units of s2
//! (3.84, or the model's own error where larger: the time step's and the cells'; where the fit does
//! not depend on its step, the part of the step's error along E is left out, as the cells' check
//! refits E), and per effect parameter the others' Jacobian columns and QR.
void setup_profile(State& s, Profile& P) {
  const Observations& obs = s.obs;
  Diagnosis& D = s.D;
  EffectContext& ctx = s.ctx;
  Evaluator& ev = *s.ev;
  const double N = s.N;
  const Candidate* best = s.best;
  P.specs = find_effect(best->effect).params(ctx, best->variant);
  const auto& specs = P.specs;
  P.pr = effect_problem(s, find_effect(best->effect), best->variant);
  const LsqProblem& pr = P.pr;
  // Jacobian at the optimum: the fit's own when it ended on one, else np runs.
  P.np = best->z.size();
  const std::size_t np = P.np;
  const auto& phys = pr.physics;
  const Eigen::VectorXd rb = weighted_residual(obs, best->pred, obs.train);
  Eigen::MatrixXd& J = P.J;
  J = best->J;
  if (J.rows() != rb.size() || J.cols() != static_cast<Eigen::Index>(np)) {
    std::vector<Physics> jb;
    std::vector<double> hstep(np);
    for (std::size_t j = 0; j < np; ++j) {
      std::vector<double> z = best->z;
      hstep[j] = pr.step[j];
      if (z[j] + hstep[j] > pr.hi[j]) hstep[j] = -hstep[j];
      z[j] += hstep[j];
      jb.push_back(phys(z));
    }
    const auto jp = ev.run(jb);
    J.resize(rb.size(), static_cast<Eigen::Index>(np));
    for (std::size_t j = 0; j < np; ++j)
      J.col(static_cast<Eigen::Index>(j)) =
          (weighted_residual(obs, jp[j], obs.train) - rb) / hstep[j];
  }
  P.s2 = best->chi2 / std::max(1.0, N - static_cast<double>(np));
  const double s2 = P.s2;
  // The threshold in units of s2: 3.84, or the model's own error where larger: the time step's and
  // the cells'. Where the fit does not depend on its step (chi-square smooth), the part of the
  // step's error along E (a phase drift E absorbs) is left out of it, as the cells' check refits E;
  // where it does, the whole of it.
  IntervalBasis& IB = D.intervals;
  if (D.time_step.done && s.half_fit.ok) {
    Eigen::VectorXd d = (4.0 / 3.0) * (weighted_residual(obs, s.half_fit, obs.train) - rb);
    const Eigen::VectorXd jE = J.col(0);
    if (!D.time_step.flagged && jE.squaredNorm() > 0) d -= jE * (jE.dot(d) / jE.squaredNorm());
    IB.chi2_time_step = d.squaredNorm();
  }
  if (IB.fit_refinement.done) IB.chi2_cells = IB.fit_refinement.chi2;
  P.thr = std::max(3.84, (IB.chi2_time_step + IB.chi2_cells) / s2);
  const double thr = P.thr;
  IB.s2 = s2;
  IB.threshold = thr;
  IB.from = thr == 3.84                          ? "noise"
            : IB.chi2_time_step >= IB.chi2_cells ? "time_step_error"
                                                 : "model_error";
  // The scan where chi-square is rough (the fit depends on its step, below).
  P.wide = D.time_step.flagged;
  P.reach = P.wide ? 1e300 : 3.0;
  P.probe = IB.from == "noise" || P.wide ? 2.0 : std::sqrt(thr);
  auto& others = P.others;
  others.resize(specs.size());
  auto& others_J = P.others_J;
  others_J.resize(specs.size());
  auto& others_qr = P.others_qr;
  others_qr.resize(specs.size());
  for (std::size_t q = 0; q < specs.size(); ++q) {
    for (std::size_t o = 0; o < np; ++o)
      if (o != 2 + q) others[q].push_back(o);
    others_J[q].resize(J.rows(), static_cast<Eigen::Index>(others[q].size()));
    for (std::size_t o = 0; o < others[q].size(); ++o)
      others_J[q].col(static_cast<Eigen::Index>(o)) =
          J.col(static_cast<Eigen::Index>(others[q][o]));
    others_qr[q].compute(others_J[q]);
  }
}

//! Where the fit depends on its step, its chi-square is rough on the scale of the step's error: two
//! probes and a quadratic through them can miss values that fit as well. Each effect parameter is
//! then also scanned over its range (kScanPoints, bounds included; the others held at the fit), and
//! the interval spans the scanned values within the threshold as well (the fit among them), widened
//! to their scanned neighbours outside it, or to the bound.
void scan(State& s, Profile& P) {
  Evaluator& ev = *s.ev;
  const Candidate* best = s.best;
  const std::vector<ParamSpec>& specs = P.specs;
  const LsqProblem& pr = P.pr;
  const auto& phys = P.pr.physics;
  const double thr = P.thr;
  const bool wide = P.wide;
  IntervalBasis& IB = s.D.intervals;
  P.scan_lo.resize(P.specs.size());
  P.scan_hi.resize(P.specs.size());
  if (!wide) return;
  {
    std::vector<Physics> scan;
    std::vector<std::vector<double>> zscan;
    for (std::size_t q = 0; q < specs.size(); ++q) {
      const std::size_t j = 2 + q;
      for (int k = 0; k < kScanPoints; ++k) {
        std::vector<double> z = best->z;
        z[j] = pr.lo[j] + (pr.hi[j] - pr.lo[j]) * k / (kScanPoints - 1);
        zscan.push_back(z);
        scan.push_back(phys(z));
      }
    }
    const auto sp = ev.run(scan);
    IB.scan_runs = static_cast<long>(scan.size());
    IB.scan_points = kScanPoints;
    for (std::size_t q = 0; q < specs.size(); ++q) {
      const std::size_t j = 2 + q;
      std::vector<std::pair<double, double>> pts = {{P.best_z[j], 0.0}};  // (z, dchi in s2)
      for (int k = 0; k < kScanPoints; ++k) {
        const std::size_t idx = q * kScanPoints + static_cast<std::size_t>(k);
        pts.emplace_back(zscan[idx][j], dchi_of(s, P, sp[idx]));
      }
      std::stable_sort(pts.begin(), pts.end());
      std::size_t first = pts.size(), last = 0;
      for (std::size_t k = 0; k < pts.size(); ++k)
        if (pts[k].second < thr) first = std::min(first, k), last = k;
      P.scan_lo[q] = first > 0 ? pts[first - 1].first : pr.lo[j];
      P.scan_hi[q] = last + 1 < pts.size() ? pts[last + 1].first : pr.hi[j];
      std::string scanned;
      for (const auto& [zv, dchi] : pts)
        scanned += fmt::format(" {:.4g}: {:.3g};", from_z(specs[q], zv), dchi);
      log::info(
          "  scan of {} (chi2 above the fit, in units of s2; threshold "
          "{:.3g}):{}",
          specs[q].name, thr, scanned);
    }
  }
}

//! Each effect parameter's interval from its two ends' crossings of the threshold (and the noise's
//! share alone where the threshold is the model's error; the scan's reach where wide).
void set_intervals(State& s, const Profile& P) {
  Diagnosis& D = s.D;
  const std::vector<ParamSpec>& specs = P.specs;
  const LsqProblem& pr = P.pr;
  const double thr = P.thr;
  const bool wide = P.wide;
  const double reach = P.reach;
  IntervalBasis& IB = s.D.intervals;
  for (std::size_t q = 0; q < specs.size(); ++q) {
    const std::size_t j = 2 + q;
    ParamEstimate& pe = D.effect_parameters[q];
    pe.ci_time_step = IB.chi2_time_step > 0 && IB.from != "noise";
    pe.ci_model_error = IB.chi2_cells > 0 && IB.from != "noise";
    for (int s = 0; s < 2; ++s) {
      const std::size_t idx = 2 * q + static_cast<std::size_t>(s);
      bool at_bound = false;
      double zend = crossing(P, idx, thr, reach, at_bound);
      if (IB.from != "noise") {  // the noise's share alone, from the same probes
        bool nb = false;
        const double v =
            from_z(specs[q], std::clamp(crossing(P, idx, 3.84, 3.0, nb), pr.lo[j], pr.hi[j]));
        (s == 0 ? pe.ci_noise_lo : pe.ci_noise_hi) = v;
      }
      if (wide) {  // the scan's reach too
        zend = s == 0 ? std::min(zend, P.scan_lo[q]) : std::max(zend, P.scan_hi[q]);
        pe.ci_scanned = true;
        if (zend <= pr.lo[j] || zend >= pr.hi[j]) at_bound = true;
      }
      zend = std::clamp(zend, pr.lo[j], pr.hi[j]);
      const double v = from_z(specs[q], zend);
      if (s == 0)
        pe.ci_lo = v, pe.ci_at_bound_lo = at_bound;
      else
        pe.ci_hi = v, pe.ci_at_bound_hi = at_bound;
    }
  }
}

}  // namespace

void check(State& s) {
  const Candidate* best = s.best;
  time_step_check(s);
  s.phase_done("time-step check");
  // The selected fit's own discretisation error, measured by select: profile intervals at the
  // noise's threshold hold only the noise's share of what the parameters do not know; where the
  // model's own error is larger, it bounds the chi-square a bias of the parameters can hide behind
  // and sets the intervals' threshold (IntervalBasis).
  if (best && !best->params.empty() && !s.opt.refinement_check) {
    s.D.intervals.fit_refinement.skipped = "switched off (--no-refinement-check)";
  }
  // Profile-likelihood intervals of the selected effect's parameters (others re-optimised: at the
  // linearised conditional optimum, then Gauss-Newton steps from there).
  if (best && !best->params.empty()) {
    Profile P;
    P.best_z = best->z;
    setup_profile(s, P);
    scan(s, P);
    probes(s, P);
    refine_probes(s, P);
    set_intervals(s, P);
  }
  s.phase_done("intervals");
}

}  // namespace gen4d::diagnose
