//! The model's own discretisation error (refinement_check: the baseline on voxels of 2h and h/2)
//! and the misfit budget (what a missing effect could explain at most), used by the refit and
//! select stages.
#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include "core/Error.hpp"
#include "core/Log.hpp"
#include "diagnose/Pipeline.hpp"
#include "diagnose/Tuning.hpp"

namespace gen4d::diagnose {

namespace {

//! The deck voxelized at another voxel size, with the channels attached there and the masks of the
//! values it can measure; fobs's values are the h run's prediction.
struct CheckLevel {
  std::unique_ptr<ForwardModel> model;
  Observations fobs;
  std::vector<char> all_in, scored_in;
  double n_scored = 0, n_in = 0;
  std::size_t channels = 0;
  std::string skipped;  //!< why the level cannot be used
};

//! The deck at cells `factor` times its own (every edge).
CheckLevel check_level(const Config& cfg, double factor, const Observations& obs,
                       const std::vector<std::array<double, 3>>& X, const Prediction& base_pred,
                       const std::vector<char>& scored, const char* what) {
  CheckLevel L;
  Config level_cfg = cfg;
  level_cfg.voxel_size = cfg.voxel_size * factor;  // cell_edges() scales the spacing along
  try {
    L.model = make_forward_model(level_cfg);
  } catch (const InputError& e) {
    L.skipped = fmt::format("the deck at {} cannot be modelled: {}", what, e.what());
    return L;
  }
  L.fobs = obs;  // same values, weights and masks; attachments on these voxels
  std::vector<char> usable(obs.requests.size(), 0);
  const Attachment* any = nullptr;
  for (std::size_t c = 0; c < obs.requests.size(); ++c) {
    if (!L.model->inside(X[c])) continue;
    L.fobs.requests[c].at = L.model->attach(X[c]);
    usable[c] = 1;
    any = &L.fobs.requests[c].at;
    ++L.channels;
  }
  if (!any) {
    L.skipped = fmt::format("no channel lies in the body voxelized at {}", what);
    return L;
  }
  for (std::size_t c = 0; c < obs.requests.size(); ++c)
    if (!usable[c]) L.fobs.requests[c].at = *any;  // sampled, never measured
  // The runs are measured against the h run: fobs's values become its prediction.
  L.fobs.y = base_pred.y;
  L.all_in.assign(obs.size(), 0);
  L.scored_in.assign(obs.size(), 0);
  for (std::size_t i = 0; i < obs.size(); ++i) {
    const auto c = static_cast<std::size_t>(obs.channel[i]);
    L.all_in[i] = usable[c];
    L.scored_in[i] = usable[c] && scored[i];
  }
  L.n_scored = static_cast<double>(std::count(scored.begin(), scored.end(), 1));
  L.n_in = static_cast<double>(std::count(L.scored_in.begin(), L.scored_in.end(), 1));
  return L;
}

//! The run of `got` closest to the h run (weighted, every usable value), and its difference times
//! `scale` as the error of the h model over the scored values (those out of the measure count at
//! the mean of the measured ones), into R.
void measure_closest(const CheckLevel& L, const std::vector<Physics>& tried,
                     const std::vector<Prediction>& got, double scale, RefinementCheck& R) {
  std::size_t best = 0;
  double best_distance = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < got.size(); ++k) {
    if (!got[k].ok) continue;
    const double d = weighted_residual(L.fobs, got[k], L.all_in).squaredNorm();
    if (d < best_distance) best_distance = d, best = k;
  }
  R.youngs_modulus = tried[best].youngs_modulus;
  const double chi2 =
      scale * scale * weighted_residual(L.fobs, got[best], L.scored_in).squaredNorm();
  R.chi2 = L.n_in > 0 ? chi2 * L.n_scored / L.n_in : 0.0;
  R.noise_sd = L.n_scored > 0 ? std::sqrt(R.chi2 / L.n_scored) : 0.0;
  R.rms = scale * rms(L.fobs, got[best], L.scored_in);  // m, or m/s^2 without markers
}

//! An evaluator's runs, their seconds and their failures, added to a check's cost.
void add_cost(RefinementCheck& R, const Evaluator& e) {
  R.runs += e.runs(), R.run_seconds += e.run_seconds(), R.idle_seconds += e.idle_seconds();
  if (R.failed == 0 && e.failed() > 0) R.first_failure = e.first_failure();
  R.failed += e.failed();
}

}  // namespace

RefinementCheck refinement_check(MPI_Comm comm, const Config& cfg, const Observations& obs,
                                 const std::vector<std::array<double, 3>>& X,
                                 const Physics& calibrated, const Prediction& base_pred,
                                 const std::vector<char>& scored, double t_free,
                                 double decided_below, bool linear_refit) {
  RefinementCheck R;
  const Vec3d dir = motion_direction(obs, t_free);
  const double w_h_rest = make_forward_model(cfg)->rest_frequency(calibrated, dir);
  // The pair starts at the E that gives the other voxels the h voxels' rest frequency (finer voxels
  // are softer in bending): at the calibrated E itself the two drift apart in phase, and the pair's
  // bound on the h model's error is then mostly a phase error that E absorbs.
  auto rest_matched = [&](const ForwardModel& m, Physics p) {
    const double w = m.rest_frequency(p, dir);
    if (std::isfinite(w_h_rest) && std::isfinite(w) && w > 0)
      p.youngs_modulus *= std::clamp(std::pow(w_h_rest / w, 2), 0.9, 1.1);
    return p;
  };
  // 1. Voxels of 2h first, when a bound would decide: the two-grid convergence index (Roache; ASME
  // V&V 20) bounds the error of the h model by Fs |u_2h - u_h| / (2^p - 1) with the safety factor
  // Fs = 3 of a two-grid study and p = 2, i.e. by the whole h-to-2h difference (three times
  // Richardson's estimate). The 2h runs cost an eighth of an h run (the h/2 runs 23x one); when
  // their bound is below `decided_below` (an effect that explains far more than any discretisation
  // error), the h/2 runs are not needed. A pre-asymptotic 2h model only widens the bound (the h/2
  // runs then decide).
  if (decided_below > 0) {
    const CheckLevel C = check_level(cfg, 2.0, obs, X, base_pred, scored, "voxel_size x 2");
    if (C.skipped.empty()) {
      Evaluator cev(comm, *C.model, C.fobs);
      Physics c0 = rest_matched(*C.model, calibrated), c1 = c0;
      c1.youngs_modulus *= 1 + kPairStep;
      const std::vector<Physics> tried = {c0, c1};
      const std::vector<Prediction> got = cev.run(tried);
      RefinementCheck Rc;
      Rc.voxel_size = 2 * cfg.voxel_size;
      Rc.voxels = C.model->voxels();
      Rc.channels = C.channels;
      add_cost(Rc, cev);
      if (got[0].ok || got[1].ok) measure_closest(C, tried, got, 1.0, Rc);
      log::info(
          "discretisation check, 2h grid ({} voxels, E {:.5g} Pa): error "
          "of the h model at "
          "most {:.3g} m rms (the h-to-2h difference, grid convergence "
          "index with Fs = 3), "
          "scored chi2 {:.4g}{}",
          Rc.voxels, Rc.youngs_modulus, Rc.rms, Rc.chi2,
          !(got[0].ok || got[1].ok)
              ? fmt::format(": both runs failed ({}), h/2 runs needed", cev.first_failure())
          : Rc.chi2 < decided_below ? std::string(": decides, no h/2 runs")
                                    : std::string(": h/2 runs needed"));
      if ((got[0].ok || got[1].ok) && Rc.chi2 < decided_below) {
        Rc.done = Rc.upper_bound = Rc.coarse = true;
        return Rc;
      }
      add_cost(R, cev);
    }
  }
  // 2. Voxels of h/2.
  const CheckLevel F = check_level(cfg, 0.5, obs, X, base_pred, scored, "voxel_size / 2");
  R.voxel_size = cfg.voxel_size / 2;
  if (!F.skipped.empty()) {
    R.skipped = F.skipped;
    return R;
  }
  const ForwardModel& fine = *F.model;
  R.voxels = fine.voxels();
  R.channels = F.channels;
  Evaluator fev(comm, fine, F.fobs);
  // The fine runs stop Newton at 1e-4 of their voxel: 0.5 % of the errors this check measures and
  // of the pair's difference (E by 0.5 %), and a quarter fewer iterations per step. They also
  // rebuild their lagged tangent only when a correction shrinks by less than 0.8 (0.5 on the h
  // model): a rebuild costs ~150 of their iterations, against ~27 of the h model's.
  Physics fine_physics = calibrated;
  fine_physics.newton_tolerance = 1e-4;
  fine_physics.refresh_contraction = 0.8;
  fine_physics = rest_matched(fine, fine_physics);
  Physics p0 = fine_physics, p1 = fine_physics;
  p1.youngs_modulus *= 1 + kPairStep;
  std::vector<Physics> tried = {p0, p1};
  std::vector<Prediction> got = fev.run(tried);
  if (!got[0].ok || !got[1].ok) {
    R.skipped =
        "the baseline fails on the finer voxels: " + (got[0].ok ? got[1].failure : got[0].failure);
    add_cost(R, fev);
    return R;
  }
  constexpr double kScale = 4.0 / 3.0;  // second order: e_h = 4/3 (u_h - u_h/2)
  // Either run of the pair bounds the error from above (E not yet refitted): when that bound is
  // already below `decided_below`, the refit cannot change what the check decides.
  measure_closest(F, tried, got, kScale, R);
  R.upper_bound = R.chi2 < decided_below;
  if (!R.upper_bound) {
    // One Gauss-Newton step in log E from the pair, at most ~10 % of E.
    const Eigen::VectorXd r0 = weighted_residual(F.fobs, got[0], F.all_in);
    const Eigen::VectorXd j = weighted_residual(F.fobs, got[1], F.all_in) - r0;
    const double jj = j.squaredNorm();
    const double s = jj > 0 ? std::clamp(-r0.dot(j) / jj, -20.0, 20.0) : 0.0;
    // Within a few steps of the pair its linearisation is the refit: the prediction at the
    // Gauss-Newton optimum, got[0] + s (got[1] - got[0]), measured as a run (the closest of the
    // three is kept, as of the four runs below).
    if (linear_refit && std::abs(s) <= kLinearRefitReach) {
      Prediction lin = got[0];
      for (std::size_t i = 0; i < lin.y.size(); ++i) lin.y[i] += s * (got[1].y[i] - got[0].y[i]);
      Physics pl = fine_physics;
      pl.youngs_modulus *= std::pow(1 + kPairStep, s);
      tried.push_back(pl);
      got.push_back(std::move(lin));
      measure_closest(F, tried, got, kScale, R);
      R.linearised = true;
      add_cost(R, fev);
      R.done = true;
      log::info(
          "discretisation check (h/2 rerun, {} voxels, E refitted to "
          "{:.5g} Pa, linearised "
          "from the pair): error of the h model {:.3g} m rms ({:.3g} "
          "noise sd), scored chi2 "
          "{:.4g} ({} runs)",
          R.voxels, R.youngs_modulus, R.rms, R.noise_sd, R.chi2, R.runs);
      return R;
    }
    std::vector<Physics> next;
    Physics pg = fine_physics;
    pg.youngs_modulus *= std::pow(1 + kPairStep, s);
    next.push_back(pg);
    const double w_h = dominant_omega(obs, base_pred.y, t_free);
    const double w_f = dominant_omega(obs, got[0].y, t_free);
    if (std::isfinite(w_h) && std::isfinite(w_f) && w_f > 0) {
      Physics pf = fine_physics;
      pf.youngs_modulus *= std::clamp(std::pow(w_h / w_f, 2), 0.9, 1.1);
      if (std::abs(pf.youngs_modulus / pg.youngs_modulus - 1) > 1e-4) next.push_back(pf);
    }
    const auto more = fev.run(next);
    tried.insert(tried.end(), next.begin(), next.end());
    got.insert(got.end(), more.begin(), more.end());
    measure_closest(F, tried, got, kScale, R);
  }
  add_cost(R, fev);
  R.done = true;
  log::info(
      "discretisation check (h/2 rerun, {} voxels, E {} {:.5g} Pa): "
      "error of the h model "
      "{}{:.3g} m rms ({:.3g} noise sd), scored chi2 {:.4g} ({} runs)",
      R.voxels, R.upper_bound ? "at the h voxels' rest frequency," : "refitted to",
      R.youngs_modulus, R.upper_bound ? "at most " : "", R.rms, R.noise_sd, R.chi2, R.runs);
  return R;
}

MisfitBudget misfit_budget(const Observations& obs, const Prediction& base,
                           const std::vector<char>& scored) {
  MisfitBudget B;
  if (!base.ok) return B;
  double res_pos = 0, res_acc = 0;
  residual_noise(obs, base, res_pos, res_acc);
  double noise_sd_acceleration = 0;  // reported where there are no markers (rms()'s units)
  for (std::size_t i = 0; i < obs.size(); ++i) {
    if (!scored[i]) continue;
    const double r = (obs.y[i] - base.y[i]) / obs.sigma[i];
    B.scored_chi2 += r * r;
    // The noise's sd relative to the weight's: the recording's own estimate (the weight) or the
    // residual's, whichever is lower (both only overestimate white noise: signal that a cubic
    // cannot follow over 7 samples leaks into them).
    const double est =
        obs.requests[static_cast<std::size_t>(obs.channel[i])].acceleration ? res_acc : res_pos;
    const double s = std::isfinite(est) ? std::min(1.0, est / obs.sigma[i]) : 1.0;
    B.noise_chi2 += s * s;
    if (est == res_pos)
      B.noise_sd = s * obs.sigma[i];
    else
      noise_sd_acceleration = s * obs.sigma[i];
  }
  if (B.noise_sd == 0) B.noise_sd = noise_sd_acceleration;
  // On held-out values the baseline's misfit is |n + b0|^2 (noise n, its systematic error b0) and
  // an effect's |n + b1|^2 >= |n|^2 - (n.u)^2 (u = b1 / |b1|, fixed by the training data, so n.u is
  // one noise sd at most in distribution): an effect explains at most the misfit less |n|^2, plus 9
  // (3 sd of n.u). |n|^2 is counted at half the estimated noise variance (the estimate may be sqrt
  // 2 high), less 3 sd of its spread over this many values.
  B.bound =
      std::max(0.0, B.scored_chi2 - kNoiseShare * B.noise_chi2 + 3 * std::sqrt(2 * B.noise_chi2)) +
      9;
  B.evaluated = kNoiseShare * B.noise_chi2 >= 0.25 * B.scored_chi2;
  return B;
}

}  // namespace gen4d::diagnose
