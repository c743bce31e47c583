//! Stage calibrate: the baseline's log E and nu fitted to the recording (density stays the deck's:
//! E/rho is identified), from a start matched on the dominant frequency; the noise weights
//! recalibrated on its residual; the misfit test (chi2/dof, whiteness).
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <utility>

#include "core/Log.hpp"
#include "diagnose/Pipeline.hpp"
#include "diagnose/Tuning.hpp"

namespace gen4d::diagnose {

Physics base_physics(const State& s, const std::vector<double>& z) {
  Physics p = s.nominal;
  p.youngs_modulus = std::exp(z[0]);
  p.poisson_ratio = s.opt.hold_poisson ? s.nominal.poisson_ratio : z[1];  // --hold-poisson
  apply_release(s, {}, 0, p);
  return p;
}

void apply_release(const State& s, const std::vector<double>& z, std::size_t first, Physics& p) {
  const std::size_t n = s.release_specs.size();
  if (n == 0) return;
  const bool own = z.size() == first + n;
  const double* v = own ? &z[first] : s.release_z.data();
  p.load_scale = from_z(s.release_specs[0], v[0]);
  p.time_offset = from_z(s.release_specs[1], v[1]);
  p.release_duration = from_z(s.release_specs[2], v[2]);
}

void add_release(const State& s, LsqProblem& pr) {
  for (std::size_t j = 0; j < s.release_specs.size(); ++j) {
    const ParamSpec& sp = s.release_specs[j];
    pr.lo.push_back(to_z(sp, sp.lo));
    pr.hi.push_back(to_z(sp, sp.hi));
    pr.step.push_back(sp.log ? 1e-3 : 1e-3 * (sp.hi - sp.lo));
    pr.tail.push_back(s.release_z[j]);
  }
}

double match_frequency(const State& s, double zE, double w_target, const Prediction& p) {
  if (!p.ok) return zE;
  return std::clamp(zE + 2 * std::log(w_target / dominant_omega(s.obs, p.y, s.t_free)), s.pb.lo[0],
                    s.pb.hi[0]);
}

namespace {

//! The number of measured series (a channel's component) among the fitted values.
std::size_t measured_series(const Observations& obs) {
  std::set<std::pair<int, int>> series;
  for (std::size_t i = 0; i < obs.size(); ++i)
    if (obs.train[i]) series.insert({obs.channel[i], obs.component[i]});
  return series.size();
}

//! The start: the nominal E, or the E that moves the dominant frequency of the motion after the
//! last load change onto the recorded one (E ~ omega^2), whichever fits better. Trajectory least
//! squares has a local minimum per period of phase error; this start avoids them.
std::vector<double> frequency_start(State& s) {
  const Observations& obs = s.obs;
  const Physics& nominal = s.nominal;
  const Prediction& nominal_pred = s.nominal_pred;
  std::vector<double> z_start = {std::log(nominal.youngs_modulus), nominal.poisson_ratio};
  const double t_free = s.t_free;
  double w_obs = dominant_omega(obs, obs.y, t_free);
  double zf = match_frequency(s, z_start[0], w_obs, nominal_pred);
  double w_sim = dominant_omega(obs, nominal_pred.y, t_free);
  if (s.D.accelerations_only && nominal_pred.ok) {
    // Accelerations weigh the higher modes by omega^2, so the crossings' frequency is a mix:
    // the first mode's own, by the sinusoid fit, near it.
    // The deck's first mode is searched near the recorded one (within 30 %): the crossings of
    // a prediction with more of its second mode than the recording would lead the search off.
    const double w_o = modal_frequencies(obs, obs.y, t_free, w_obs).omega1;
    const double w_s = modal_frequencies(obs, nominal_pred.y, t_free, w_o > 0 ? w_o : w_sim).omega1;
    if (w_o > 0 && w_s > 0) {
      w_obs = w_o, w_sim = w_s;
      zf = std::clamp(z_start[0] + 2 * std::log(w_obs / w_sim), s.pb.lo[0], s.pb.hi[0]);
    }
  }
  if (std::isfinite(zf) && std::abs(zf - z_start[0]) > 1e-3) {
    const Prediction pf = s.ev->run_one(base_physics(s, {zf, z_start[1]}));
    const double c0 = weighted_residual(obs, nominal_pred, obs.train).squaredNorm();
    const double c1 = weighted_residual(obs, pf, obs.train).squaredNorm();
    log::info(
        "frequency start: recorded {:.4g} rad/s, nominal deck {:.4g} "
        "rad/s -> E {:.4g} Pa "
        "(chi2 {:.4g} vs {:.4g} at the deck's E)",
        w_obs, w_sim, std::exp(zf), c1, c0);
    if (pf.ok && c1 < c0) z_start[0] = zf;
  }
  return z_start;
}

//! The noise level, calibrated: the recording's own estimate counts as noise whatever motion a
//! cubic cannot follow over 7 samples; the calibrated deck's residual has most of that motion
//! removed. The lower of the two weighs every value from here on.
void recalibrate_noise(State& s) {
  Diagnosis& D = s.D;
  Observations& obs = s.obs;
  LsqResult& base = s.base;
  D.noise_recording_position = D.noise_position;
  D.noise_recording_acceleration = D.noise_acceleration;
  if (base.pred.ok) {
    double res_pos = 0, res_acc = 0;
    residual_noise(obs, base.pred, res_pos, res_acc);
    if (res_pos > 0 && res_pos < D.noise_position) D.noise_position = res_pos;
    if (res_acc > 0 && res_acc < D.noise_acceleration) D.noise_acceleration = res_acc;
    Eigen::Index k = 0;
    for (std::size_t i = 0; i < obs.size(); ++i) {
      const bool acc = obs.requests[static_cast<std::size_t>(obs.channel[i])].acceleration;
      const double sigma = acc ? D.noise_acceleration : D.noise_position;
      if (obs.train[i] && k < base.J.rows()) base.J.row(k) *= obs.sigma[i] / sigma;
      k += obs.train[i] ? 1 : 0;
      obs.sigma[i] = sigma;
    }
    base.r = weighted_residual(obs, base.pred, obs.train);
    base.chi2 = base.r.squaredNorm();
    if (D.noise_position < D.noise_recording_position)
      log::info(
          "noise from the calibrated deck's residual: {:.3g} m (the "
          "recording's {:.3g} m)",
          D.noise_position, D.noise_recording_position);
  }
  D.youngs_modulus = std::exp(base.z[0]);
  D.poisson_ratio = base.z[1];
  D.baseline_pred = base.pred;
  D.rms_before = rms(obs, base.pred, obs.train);
  D.heldout_rms_before = rms(obs, base.pred, obs.heldout);
}

}  // namespace

//! A deck whose body starts pre-loaded ([[force]] start < 0, a pluck) was released from a state
//! nobody measured, at a time known to a few milliseconds, over a few milliseconds: the
//! pre-load's scale (the deck's value is a guess; 1/5 to 5 times it), the model's time at the
//! recording's t = 0 (within 5 model steps or 10 ms, whichever is more) and the release's
//! duration (one model step to 10 ms, from 2 ms) join E and nu in the calibration.
void release_state(State& s) {
  if (!s.release_specs.empty() ||
      std::none_of(s.cfg.forces.begin(), s.cfg.forces.end(),
                   [](const ForceConfig& f) { return f.start < 0; }) ||
      s.model->kind() != "voxel")
    return;
  const double reach = std::max(0.01, 5 * s.nominal.dt);
  const double longest = std::max(0.01, 2 * s.nominal.dt);
  s.release_specs = {{"preload_scale", "", 0.2, 5.0, true, 1.0},
                     {"time_offset", "s", -reach, reach, false, reach},
                     {"release_duration", "s", s.nominal.dt, longest, false, longest}};
  s.release_z = {to_z(s.release_specs[0], 1.0), 0.0, std::clamp(0.002, s.nominal.dt, longest)};
}

void calibrate(State& s) {
  Diagnosis& D = s.D;
  const Observations& obs = s.obs;
  const Physics& nominal = s.nominal;
  release_state(s);
  // nu stops at kMaxPoisson: the voxel element (full integration) locks volumetrically as nu nears
  // 1/2, and a fit then uses nu as a second stiffness knob.
  const std::vector<ParamSpec> base_specs = {
      {"youngs_modulus", "Pa", nominal.youngs_modulus / 3, nominal.youngs_modulus * 3, true},
      {"poisson_ratio", "", 0.0, std::max(kMaxPoisson, nominal.poisson_ratio), false}};
  LsqProblem& pb = s.pb;
  pb.lo = {to_z(base_specs[0], base_specs[0].lo), base_specs[1].lo};
  pb.hi = {to_z(base_specs[0], base_specs[0].hi), base_specs[1].hi};
  D.one_series = measured_series(obs) < 2;
  D.poisson_held = s.opt.hold_poisson;
  if (D.poisson_held) {
    pb.lo[1] = pb.hi[1] = nominal.poisson_ratio;  // its runs are the memo's: no cost
    log::info("nu held at the deck's {:.3g} (--hold-poisson)", nominal.poisson_ratio);
  }
  pb.step = {1e-3, 1e-2};  // nu moves a beam little: a larger step keeps
                           // Newton's tolerance out
  pb.physics = [&s](const std::vector<double>& z) {
    Physics p = base_physics(s, z);
    apply_release(s, z, 2, p);
    return p;
  };
  add_release(s, pb);
  pb.mask = &s.obs.train;
  s.events = s.model->load_events();
  s.t_free = s.events.empty() ? 0.0 : s.events.back();  // motion after the last load
  const std::vector<double> z_start = frequency_start(s);
  s.base = least_squares(*s.ev, pb, z_start, s.opt.max_iterations);
  LsqResult& base = s.base;
  // The release state is held from here on (every later fit carries it as a tail); the
  // baseline's z is (log E, nu) as the effects' problems expect.
  if (!s.release_specs.empty()) {
    s.release_z.assign(base.z.begin() + 2, base.z.end());
    base.z.resize(2);
    for (std::size_t j = 0; j < s.release_specs.size(); ++j)
      D.release.push_back({s.release_specs[j].name, s.release_specs[j].unit,
                           from_z(s.release_specs[j], s.release_z[j])});
    log::info("release state: pre-load x {:.4g}, time offset {:.4g} s, released over {:.3g} s",
              from_z(s.release_specs[0], s.release_z[0]),
              from_z(s.release_specs[1], s.release_z[1]),
              from_z(s.release_specs[2], s.release_z[2]));
  }
  recalibrate_noise(s);
  const double N = s.N;
  const double chi2_0 = base.chi2;
  D.chi2_red = chi2_0 / std::max(1.0, N - 2);
  whiteness(obs, base.pred, D.whiteness_p, D.lag1);
  D.misfit = D.chi2_red > 1 + 4 * std::sqrt(2 / std::max(1.0, N - 2)) || D.whiteness_p < 1e-3;
  log::info(
      "calibrated: E {:.4g} Pa (nominal {:.4g}), nu {:.3f}; rms {:.3g} "
      "m, chi2/dof {:.3g}, "
      "whiteness p {:.2g} ({} runs)",
      D.youngs_modulus, nominal.youngs_modulus, D.poisson_ratio, D.rms_before, D.chi2_red,
      D.whiteness_p, s.ev->runs());
  s.chi2_0 = base.chi2;
  s.calibrated = base_physics(s, base.z);
  s.phase_done("calibration");
}

}  // namespace gen4d::diagnose
