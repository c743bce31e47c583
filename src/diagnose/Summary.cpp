//! Stage report: signatures of the calibrated deck's misfit (amplitude decay, frequency shift,
//! offsets, mode shape), the candidates listed, the cost summed, and the files written
//! (write_reports).
#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>

#include "core/Log.hpp"
#include "forward/ElementKernel.hpp"
#include "diagnose/Pipeline.hpp"
#include "parallel/Comm.hpp"

namespace gen4d::diagnose {

namespace {

//! The channel whose calibrated rms error is the largest.
int worst_channel(const Diagnosis& D) {
  std::size_t w = 0;
  for (std::size_t c = 0; c < D.channel_rms_before.size(); ++c)
    if (D.channel_rms_before[c] > D.channel_rms_before[w]) w = c;
  return static_cast<int>(w);
}

//! On the worst marker's main component, per period after the last load change: obs - mean = alpha
//! (sim - mean) + beta dsim/dt, shift = -beta / alpha; the trends of alpha (amplitude decay) and of
//! the shift (frequency), the mean offset and the offset at the start (a permanent set).
std::vector<Signature> window_signatures(const State& s, int worst, int comp) {
  const Observations& obs = s.obs;
  const EffectContext& ctx = s.ctx;
  const LsqResult& base = s.base;
  const std::vector<double>& events = s.events;
  const double tb = s.tb;
  const double te = s.te;
  const Diagnosis& D = s.D;
  const double t_sig = events.empty() ? tb : events.back();  // signatures from here
  const double T = 2 * kPi / ctx.omega;
  const bool acc = obs.requests[static_cast<std::size_t>(worst)].acceleration;
  const char* unit = acc ? "m/s^2" : "m";
  const double noise = acc ? D.noise_acceleration : D.noise_position;
  // Per window: obs - mean = alpha (sim - mean) + beta dsim/dt; shift = -beta/alpha.
  struct Win {
    double t, alpha, shift, offset;
  };
  std::vector<double> ts, yo, ys;
  for (std::size_t i = 0; i < obs.size(); ++i)
    if (obs.channel[i] == worst && obs.component[i] == comp) {
      ts.push_back(obs.t[i]);
      yo.push_back(obs.y[i]);
      ys.push_back(base.pred.y[i]);
    }
  std::vector<Win> wins;
  for (double w0 = t_sig; w0 + T <= te + 1e-12; w0 += T) {
    std::vector<std::size_t> idx;
    for (std::size_t i = 0; i < ts.size(); ++i)
      if (ts[i] >= w0 && ts[i] < w0 + T) idx.push_back(i);
    if (idx.size() < 6) continue;
    double mo = 0, ms = 0;
    for (auto i : idx) mo += yo[i], ms += ys[i];
    mo /= static_cast<double>(idx.size());
    ms /= static_cast<double>(idx.size());
    Eigen::MatrixXd A(static_cast<Eigen::Index>(idx.size()), 2);
    Eigen::VectorXd b(static_cast<Eigen::Index>(idx.size()));
    for (std::size_t k = 0; k < idx.size(); ++k) {
      const std::size_t i = idx[k];
      const std::size_t a = i ? i - 1 : i, c = std::min(i + 1, ts.size() - 1);
      A(static_cast<Eigen::Index>(k), 0) = ys[i] - ms;
      A(static_cast<Eigen::Index>(k), 1) = (ys[c] - ys[a]) / std::max(ts[c] - ts[a], 1e-12);
      b[static_cast<Eigen::Index>(k)] = yo[i] - mo;
    }
    const Eigen::Vector2d x = A.colPivHouseholderQr().solve(b);
    if (std::abs(x[0]) < 1e-6) continue;
    wins.push_back({w0 + 0.5 * T, x[0], -x[1] / x[0], mo - ms});
  }
  Signature amp{"amplitude_decay", false, 0, ""}, freq{"frequency_shift", false, 0, ""},
      off{"static_offset", false, 0, ""}, perm{"permanent_set", false, 0, ""};
  if (wins.size() >= 3) {
    // Slopes by least squares.
    auto slope = [&](auto get) {
      double st = 0, sy = 0, stt = 0, sty = 0, n = 0;
      for (const Win& w : wins) {
        const double y = get(w);
        st += w.t, sy += y, stt += w.t * w.t, sty += w.t * y, n += 1;
      }
      return (n * sty - st * sy) / std::max(n * stt - st * st, 1e-300);
    };
    const double dlnA =
        slope([](const Win& w) { return std::log(std::max(std::abs(w.alpha), 1e-9)); });
    const double dshift = slope([](const Win& w) { return w.shift; });
    amp.value = dlnA;
    amp.present = dlnA < -0.02 && std::abs(wins.back().alpha / wins.front().alpha - 1) > 0.05;
    amp.detail = fmt::format(
        "observed/simulated amplitude ratio changes at {:+.3g} per s "
        "({:.3g} -> {:.3g})",
        dlnA, wins.front().alpha, wins.back().alpha);
    freq.value = dshift;
    freq.present = std::abs(dshift) > 0.005;
    freq.detail = fmt::format(
        "phase lag grows at {:.3g} s/s: the observed frequency is {:+.2f} % "
        "of the simulated",
        dshift, -100 * dshift);
    double mo = 0;
    for (const Win& w : wins) mo += w.offset;
    mo /= static_cast<double>(wins.size());
    off.value = mo;
    off.present = !acc && std::abs(mo) > 3 * noise;
    off.detail = fmt::format("mean offset {:.3g} {} after {:g} s ({:.1f} noise sd){}", mo, unit,
                             t_sig, mo / noise,
                             acc ? ": not a deformation (a mean acceleration is the sensor's bias "
                                   "or drift), so not a signature of accelerometers"
                                 : "");
    // Offset present from the start (load/gravity) or only after loading (permanent set).
    double early = 0;
    int ne = 0;
    for (std::size_t i = 0; i < ts.size(); ++i)
      if (ts[i] < tb + 0.05 * (te - tb)) early += yo[i] - ys[i], ++ne;
    early = ne ? early / ne : 0;
    perm.value = mo - early;
    perm.present = off.present && std::abs(early) < 0.3 * std::abs(mo) && !events.empty();
    perm.detail = fmt::format(
        "offset {0:.3g} {2} at the start, {1:.3g} {2} after the load is removed", early, mo, unit);
  }
  return {amp, freq, off, perm};
}

//! Mode shape: the spread over markers of the observed/simulated amplitude ratio.
Signature mode_signature(const State& s, int comp, double t_sig) {
  const Observations& obs = s.obs;
  const LsqResult& base = s.base;
  const Diagnosis& D = s.D;
  Signature mode{"mode_shape_change", false, 0, ""};
  {
    std::vector<double> ratio;
    for (std::size_t c = 0; c < obs.requests.size(); ++c) {
      double so = 0, ss = 0;
      std::vector<double> o, sim;
      for (std::size_t i = 0; i < obs.size(); ++i)
        if (obs.channel[i] == static_cast<int>(c) && obs.component[i] == comp && obs.t[i] >= t_sig)
          o.push_back(obs.y[i]), sim.push_back(base.pred.y[i]);
      if (o.size() < 4) continue;
      const double mo = std::accumulate(o.begin(), o.end(), 0.0) / static_cast<double>(o.size());
      const double ms =
          std::accumulate(sim.begin(), sim.end(), 0.0) / static_cast<double>(sim.size());
      for (std::size_t k = 0; k < o.size(); ++k)
        so += std::pow(o[k] - mo, 2), ss += std::pow(sim[k] - ms, 2);
      const double noise = obs.requests[c].acceleration ? D.noise_acceleration : D.noise_position;
      if (ss > std::pow(5 * noise, 2) * static_cast<double>(o.size()))
        ratio.push_back(std::sqrt(so / ss));
    }
    if (ratio.size() >= 3) {
      const double m =
          std::accumulate(ratio.begin(), ratio.end(), 0.0) / static_cast<double>(ratio.size());
      double v = 0;
      for (double r : ratio) v += (r - m) * (r - m);
      mode.value = std::sqrt(v / static_cast<double>(ratio.size() - 1)) / m;
      mode.present = mode.value > 0.05;
      mode.detail = fmt::format("observed/simulated amplitude varies by {:.1f} % between markers",
                                100 * mode.value);
    }
  }
  return mode;
}

//! The candidates reported: the kept variants, the other refitted ones, the screened rest.
void list_candidates(State& s) {
  Diagnosis& D = s.D;
  const std::vector<Candidate>& screened = s.screened;
  std::vector<Candidate>& variant_fits = s.variant_fits;
  std::vector<Candidate>& fits = s.fits;
  D.candidates = fits;
  for (const Candidate& v : variant_fits)
    if (std::none_of(fits.begin(), fits.end(), [&](const Candidate& f) {
          return f.effect == v.effect && f.variant == v.variant;
        }))
      D.candidates.push_back(v);
  for (const Candidate& sc : screened)
    if (std::none_of(D.candidates.begin(), D.candidates.end(), [&](const Candidate& f) {
          return f.effect == sc.effect && f.variant == sc.variant;
        }))
      D.candidates.push_back(sc);
}

//! The cost: the discretisation checks' own runs (their evaluators) count with the rest.
void sum_cost(State& s) {
  Diagnosis& D = s.D;
  Evaluator& ev = *s.ev;
  const auto wall0 = s.wall0;
  const RefinementCheck& FR = D.intervals.fit_refinement;
  D.runs = ev.runs() + D.refinement.runs + FR.runs;
  D.runs_reused = ev.reused();
  D.failed_runs = ev.failed() + D.refinement.failed + FR.failed;
  D.first_failure = ev.failed() > 0           ? ev.first_failure()
                    : D.refinement.failed > 0 ? D.refinement.first_failure
                                              : FR.first_failure;
  D.continued_runs = ev.continued();
  if (D.continued_runs > 0)
    log::info(
        "{} of {} forward runs compressed StVK voxels past the stretch "
        "{} (stress continued "
        "below it)",
        D.continued_runs, ev.runs(), kStvkContinuedStretch);
  if (D.failed_runs > 0)
    log::info("{} of {} forward runs failed; the first: {}", D.failed_runs, ev.runs(),
              D.first_failure);
  D.run_seconds = ev.run_seconds() + D.refinement.run_seconds + FR.run_seconds;
  D.idle_seconds = ev.idle_seconds() + D.refinement.idle_seconds + FR.idle_seconds;
  D.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  log::info(
      "verdict: {}{}; rms {:.3g} -> {:.3g} m, held-out {:.3g} -> "
      "{:.3g} m ({} runs, {} reused, "
      "{:.1f} s)",
      D.verdict, D.effect.empty() ? "" : " (" + D.effect + ")", D.rms_before, D.rms_after,
      D.heldout_rms_before, D.heldout_rms_after, D.runs, D.runs_reused, D.wall_seconds);
}

}  // namespace

namespace {

//! The two lowest modal frequencies of the recording and of the final fit (after the last load
//! change), and the fit's modal damping ratios of those modes where it has Rayleigh damping:
//! zeta_i = alpha / (2 omega_i) + beta omega_i / 2.
void modal_summary(State& s) {
  Diagnosis& D = s.D;
  const double two_pi = 2 * std::acos(-1.0);
  D.modes_measured = {s.modes.omega1 / two_pi, s.modes.omega2 / two_pi};
  if (!D.fitted_pred.ok || !(s.modes.omega1 > 0)) return;
  const ModalFrequencies f =
      modal_frequencies(s.obs, D.fitted_pred.y, s.t_free, s.modes.omega1, s.modes.omega2);
  D.modes_fitted = {f.omega1 / two_pi, f.omega2 / two_pi};
  if (D.effect == "damping") {
    double alpha = 0, beta = 0;
    for (const ParamEstimate& p : D.effect_parameters) {
      if (p.name == "alpha") alpha = p.value;
      if (p.name == "beta") beta = p.value;
    }
    for (int m = 0; m < 2; ++m) {
      const double w = (m == 0 ? f.omega1 : f.omega2);
      if (w > 0) D.modal_damping[static_cast<std::size_t>(m)] = alpha / (2 * w) + beta * w / 2;
    }
  }
  log::info("modes: measured {:.4g} Hz, {:.4g} Hz; fitted {:.4g} Hz, {:.4g} Hz{}",
            D.modes_measured[0], D.modes_measured[1], D.modes_fitted[0], D.modes_fitted[1],
            std::isnan(D.modal_damping[0])
                ? std::string()
                : fmt::format("; modal damping {:.3g} %, {:.3g} %", 100 * D.modal_damping[0],
                              100 * D.modal_damping[1]));
}

}  // namespace

void report(State& s) {
  Diagnosis& D = s.D;
  modal_summary(s);
  // Signatures of the calibrated deck's misfit (on the worst marker's main component).
  {
    const int worst = worst_channel(D);
    const double t_sig = s.events.empty() ? s.tb : s.events.back();  // signatures from here
    const int comp = main_component(s.obs, worst);
    D.signatures = window_signatures(s, worst, comp);
    D.signatures.push_back(mode_signature(s, comp, t_sig));
  }
  list_candidates(s);
  D.bin_e_after = bin_energy(s, D.fitted_pred);
  D.channel_rms_after = channel_rms(s, D.fitted_pred);
  s.phase_done("signatures");
  sum_cost(s);
  if (s.rank == 0) write_reports(s.opt.out_dir, D, s.obs);
  parallel::barrier(s.comm);
}

}  // namespace gen4d::diagnose
