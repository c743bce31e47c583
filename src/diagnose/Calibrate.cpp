//! Stage calibrate: the baseline's log E and nu fitted to the recording (density stays the deck's:
//! E/rho is identified), from a start matched on the dominant frequency; the noise weights
//! recalibrated on its residual; the misfit test (chi2/dof, whiteness).
#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "core/Log.hpp"
#include "diagnose/Pipeline.hpp"
#include "diagnose/Tuning.hpp"

namespace gen4d::diagnose {

Physics base_physics(const State& s, const std::vector<double>& z) {
  Physics p = s.nominal;
  p.youngs_modulus = std::exp(z[0]);
  p.poisson_ratio = z[1];
  return p;
}

double match_frequency(const State& s, double zE, double w_target, const Prediction& p) {
  if (!p.ok) return zE;
  return std::clamp(zE + 2 * std::log(w_target / dominant_omega(s.obs, p.y, s.t_free)), s.pb.lo[0],
                    s.pb.hi[0]);
}

namespace {

//! The start: the nominal E, or the E that moves the dominant frequency of the motion after the
//! last load change onto the recorded one (E ~ omega^2), whichever fits better. Trajectory least
//! squares has a local minimum per period of phase error; this start avoids them.
std::vector<double> frequency_start(State& s) {
  const Observations& obs = s.obs;
  const Physics& nominal = s.nominal;
  const Prediction& nominal_pred = s.nominal_pred;
  std::vector<double> z_start = {std::log(nominal.youngs_modulus), nominal.poisson_ratio};
  const double t_free = s.t_free;
  const double w_obs = dominant_omega(obs, obs.y, t_free);
  const double zf = match_frequency(s, z_start[0], w_obs, nominal_pred);
  const double w_sim = dominant_omega(obs, nominal_pred.y, t_free);
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

void calibrate(State& s) {
  Diagnosis& D = s.D;
  const Observations& obs = s.obs;
  const Physics& nominal = s.nominal;
  // nu stops at kMaxPoisson: the voxel element (full integration) locks volumetrically as nu nears
  // 1/2, and a fit then uses nu as a second stiffness knob.
  const std::vector<ParamSpec> base_specs = {
      {"youngs_modulus", "Pa", nominal.youngs_modulus / 3, nominal.youngs_modulus * 3, true},
      {"poisson_ratio", "", 0.0, std::max(kMaxPoisson, nominal.poisson_ratio), false}};
  LsqProblem& pb = s.pb;
  pb.lo = {to_z(base_specs[0], base_specs[0].lo), base_specs[1].lo};
  pb.hi = {to_z(base_specs[0], base_specs[0].hi), base_specs[1].hi};
  pb.step = {1e-3, 1e-2};  // nu moves a beam little: a larger step keeps
                           // Newton's tolerance out
  pb.physics = [&s](const std::vector<double>& z) { return base_physics(s, z); };
  pb.mask = &s.obs.train;
  s.events = s.model->load_events();
  s.t_free = s.events.empty() ? 0.0 : s.events.back();  // motion after the last load
  const std::vector<double> z_start = frequency_start(s);
  s.base = least_squares(*s.ev, pb, z_start, s.opt.max_iterations);
  LsqResult& base = s.base;
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
