//! Stage observe: the effect library the model represents, the recording as observations (holdout
//! split, noise weights) and the solver's own numerical dissipation (a dt/2 rerun).
#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>

#include "core/Error.hpp"
#include "core/Log.hpp"
#include "diagnose/Pipeline.hpp"
#include "diagnose/Tuning.hpp"
#include "parallel/Comm.hpp"

namespace gen4d::diagnose {

double estimate_noise(const std::vector<const Channel*>& chans) {
  std::vector<double> est;
  std::vector<std::size_t> k;  // the samples of one component that were measured
  for (const Channel* c : chans)
    for (int d = 0; d < 3; ++d) {
      k.clear();
      for (std::size_t j = 0; j < c->t.size(); ++j)
        if (c->has(j, d)) k.push_back(j);
      for (std::size_t b = 0; b + 7 <= k.size(); b += 7) {
        Eigen::Matrix<double, 7, 4> A;
        Eigen::Matrix<double, 7, 1> y;
        const double tm = c->t[k[b + 3]];
        const double s = std::max(c->t[k[b + 6]] - c->t[k[b]], 1e-300);
        for (int i = 0; i < 7; ++i) {
          const std::size_t j = k[b + static_cast<std::size_t>(i)];
          const double x = (c->t[j] - tm) / s;
          A(i, 0) = 1, A(i, 1) = x, A(i, 2) = x * x, A(i, 3) = x * x * x;
          y[i] = c->value[j][static_cast<std::size_t>(d)];
        }
        const Eigen::Vector4d coef = A.colPivHouseholderQr().solve(y);
        est.push_back((y - A * coef).squaredNorm() / 3.0);
      }
    }
  if (est.empty()) return std::nan("");
  return std::sqrt(median(est) / 0.789);
}

namespace {

//! Observations of the recording: channel requests, holdout split, noise weights.
Observations build_observations(const ForwardModel& model, const Recording& rec, double holdout,
                                double& noise_pos, double& noise_acc) {
  Observations obs;
  std::vector<const Channel*> pos, acc;
  for (const Channel& c : rec.channels) (c.kind == ChannelKind::Position ? pos : acc).push_back(&c);
  noise_pos = estimate_noise(pos);
  noise_acc = estimate_noise(acc);
  if (!pos.empty() && !(noise_pos > 0))
    throw InputError(rec.source + ": cannot estimate the noise: a marker needs at least 7 samples");
  if (!acc.empty() && !(noise_acc > 0))
    throw InputError(rec.source + ": cannot estimate the noise: a sensor needs at least 7 samples");
  // Held out: contiguous time blocks (of 8) and markers, spread evenly.
  const double tb = rec.t_begin(), te = rec.t_end();
  const int nblocks = 8;
  std::vector<char> block_out(nblocks, 0);
  const int hb = holdout > 0 ? std::max(1, static_cast<int>(std::lround(holdout * nblocks))) : 0;
  for (int i = 0; i < hb; ++i)
    block_out[static_cast<std::size_t>((2 * i + 1) * nblocks / (2 * hb))] = 1;
  const std::size_t nch = rec.channels.size();
  // Masks only where some value is not measured: a full recording's observations are as ever.
  const bool partial = std::any_of(rec.channels.begin(), rec.channels.end(),
                                   [](const Channel& c) { return !c.measured.empty(); });
  std::vector<char> chan_out(nch, 0);
  const int hm =
      nch >= 4 && holdout > 0
          ? std::max(1, static_cast<int>(std::lround(holdout * static_cast<double>(nch))))
          : 0;
  for (int i = 0; i < hm; ++i)
    chan_out[static_cast<std::size_t>((2 * i + 1) * static_cast<int>(nch) / (2 * hm))] = 1;
  for (std::size_t c = 0; c < nch; ++c) {
    const Channel& ch = rec.channels[c];
    if (ch.kind == ChannelKind::Acceleration && !model.samples_accelerations())
      throw InputError(
          fmt::format("{}:{}: sensor '{}': the {} model samples marker positions only; "
                      "give this scene's motion as markers",
                      ch.file, ch.line.front(), ch.id, model.kind()));
    ChannelRequest r;
    r.at = model.attach(ch.X);
    r.acceleration = ch.kind == ChannelKind::Acceleration;
    r.t = ch.t;
    obs.requests.push_back(r);
    obs.ids.push_back(ch.id);
    if (partial) {
      auto& m = obs.measured.emplace_back();
      if (!ch.measured.empty()) m.resize(3 * ch.t.size());
      for (std::size_t k = 0; k < ch.t.size() && !m.empty(); ++k)
        for (int d = 0; d < 3; ++d) m[3 * k + static_cast<std::size_t>(d)] = ch.has(k, d) ? 1 : 0;
    }
    const double sigma = r.acceleration ? noise_acc : noise_pos;
    for (std::size_t k = 0; k < ch.t.size(); ++k) {
      int blk = te > tb ? static_cast<int>((ch.t[k] - tb) / (te - tb) * nblocks) : 0;
      blk = std::clamp(blk, 0, nblocks - 1);
      const bool out = block_out[static_cast<std::size_t>(blk)] || chan_out[c];
      for (int d = 0; d < 3; ++d) {
        if (!ch.has(k, d)) continue;  // not measured: never a value
        obs.y.push_back(ch.value[k][static_cast<std::size_t>(d)]);
        obs.t.push_back(ch.t[k]);
        obs.channel.push_back(static_cast<int>(c));
        obs.component.push_back(d);
        obs.sigma.push_back(sigma);
        obs.train.push_back(out ? 0 : 1);
        obs.heldout.push_back(out ? 1 : 0);
      }
    }
  }
  return obs;
}

//! The library: every effect the forward model represents (or those --effects names, each of which
//! it must represent).
void open_library(State& s) {
  const ForwardModel& model = *s.model;
  Diagnosis& D = s.D;
  std::vector<const Effect*>& library = s.library;
  const bool all = s.opt.effects.size() == 1 && s.opt.effects[0] == "all";
  if (s.opt.effects.empty() || all) {
    for (const auto& e : effect_library()) {
      if (!all && !e->in_default_library()) continue;  // only when --effects names it
      if (model.models(e->name(), ""))
        library.push_back(e.get());
      else
        D.effects_left_out.push_back({e->name(), model.unsupported_reason(e->name())});
    }
  } else {
    for (const auto& n : s.opt.effects) {
      const Effect& e = find_effect(n);
      if (!model.models(n, ""))
        throw InputError(
            fmt::format("gen4d diagnose: --effects {}: the {} model of {} does not "
                        "represent it ({})",
                        n, model.kind(), s.cfg.source, model.unsupported_reason(n)));
      library.push_back(&e);
    }
  }
  for (const auto& [name, why] : D.effects_left_out)
    log::info("effect {} left out of the library: {}", name, why);
}

//! The recording read, checked against the body, and its observations and evaluator.
void read_observations(State& s) {
  const ForwardModel& model = *s.model;
  Diagnosis& D = s.D;
  Recording& rec = s.rec;
  ReadOptions ro;
  ro.unmeasured = s.opt.unmeasured;
  rec = read_recording(s.opt.recordings[0], ro);
  for (std::size_t i = 1; i < s.opt.recordings.size(); ++i)
    merge_recordings(rec, read_recording(s.opt.recordings[i], ro));
  D.recording = rec.source;
  check_attached(rec, [&](const std::array<double, 3>& X) { return model.inside(X); });
  for (const Channel& c : rec.channels)
    if (c.t.front() < 0)
      throw InputError(
          fmt::format("{}:{}: {} '{}' has a sample at t = {} s before the deck's "
                      "start (t = 0)",
                      c.file, c.line.front(), id_column(c.kind), c.id, c.t.front()));
  s.obs = build_observations(model, rec, s.opt.holdout, D.noise_position, D.noise_acceleration);
  if (s.opt.lowpass_hz > 0 && model.kind() != "voxel")
    throw InputError("command line: --lowpass: the " + model.kind() +
                     " model samples without a filter (voxel decks take it)");
  for (const Channel& c : rec.channels)
    if (s.opt.lowpass_hz > 0 && c.t.size() > 1) {
      const double span = (c.t.back() - c.t.front()) / static_cast<double>(c.t.size() - 1);
      if (s.opt.lowpass_hz >= 0.5 / span)
        throw InputError(fmt::format(
            "command line: --lowpass {} Hz is at or above the Nyquist frequency ({:.4g} Hz) of "
            "{} '{}' in {}",
            s.opt.lowpass_hz, 0.5 / span, id_column(c.kind), c.id, c.file));
    }
  const Observations& obs = s.obs;
  D.accelerations_only =
      !obs.requests.empty() && std::all_of(obs.requests.begin(), obs.requests.end(),
                                           [](const ChannelRequest& r) { return r.acceleration; });
  s.ev = std::make_unique<Evaluator>(s.comm, model, s.obs);
  long ntrain = 0;
  for (char c : obs.train) ntrain += c;
  s.ntrain = ntrain;
  s.N = static_cast<double>(ntrain);
  const std::size_t unmeasured = 3 * rec.samples() - obs.size();
  log::info(
      "gen4d diagnose: {} channels, {} values ({} fitted, {} held out{}); noise {}{}",
      rec.channels.size(), obs.size(), ntrain, obs.size() - static_cast<std::size_t>(ntrain),
      unmeasured > 0 ? fmt::format("; {} not measured, left out", unmeasured) : std::string(),
      std::isnan(D.noise_position) ? std::string() : fmt::format("{:.3g} m", D.noise_position),
      std::isnan(D.noise_acceleration)
          ? std::string()
          : fmt::format("{}{:.3g} m/s^2 (accelerometers)", std::isnan(D.noise_position) ? "" : ", ",
                        D.noise_acceleration));
}

//! The solver's own numerical dissipation: the nominal deck rerun at dt/2; dt is halved where its
//! amplitude error could pass for an effect.
void numerical_check(State& s) {
  const Observations& obs = s.obs;
  const Recording& rec = s.rec;
  Diagnosis& D = s.D;
  Evaluator& ev = *s.ev;
  Physics& nominal = s.nominal;
  nominal = s.model->nominal();
  release_state(s);  // a pre-loaded deck: released as its fit starts
  apply_release(s, {}, 0, nominal);
  nominal.lowpass_hz = s.opt.lowpass_hz;
  D.youngs_nominal = nominal.youngs_modulus;
  D.poisson_nominal = nominal.poisson_ratio;
  D.density = nominal.density;
  Physics half = nominal;
  half.dt /= 2;
  const auto p = ev.run({nominal, half});
  if (!p[0].ok) throw RuntimeError(s.cfg.source + ": the nominal deck fails: " + p[0].failure);
  // Dissipation: the motion's amplitude over the last quarter of the record (about each channel's
  // mean there) at dt and dt/2. The trapezoidal rule conserves energy, so only a change of
  // amplitude counts; a phase change (dispersion) is reported, and absorbed by E. A pre-loaded
  // deck's amplitude is a fitted unknown (the pre-load's scale): there the dt/2 run's late
  // amplitude is first scaled by the two runs' ratio over the first quarter (how strongly a
  // release over a few steps excites the modes depends on dt; only the decay is dissipation),
  // and both windows are Hann-tapered: a lightly damped ring-down's window holds a few periods
  // of a large mode, whose untapered rms moves with its phase (the dispersion) by far more than
  // the noise (the strip: 11 noise sd of "amplitude change" from a phase shift alone).
  const double span = rec.t_end() - rec.t_begin();
  const bool taper = !s.release_specs.empty();
  auto amplitudes = [&](double t0, double t1) {  // rms about the window's means, noise units
    double a0 = 0, a1 = 0;
    std::map<int, std::array<double, 4>> mean;  // sums of w y (dt, dt/2) and of w, and count
    double nl = 0;
    const double pi = std::acos(-1.0);
    for (int pass = 0; pass < 2; ++pass)
      for (std::size_t i = 0; i < obs.size(); ++i) {
        if (obs.t[i] < t0 || obs.t[i] > t1 || !p[1].ok) continue;
        const double w = taper ? std::pow(std::sin(pi * (obs.t[i] - t0) / (t1 - t0)), 2) : 1.0;
        const int key = 3 * obs.channel[i] + obs.component[i];
        auto& m = mean[key];
        if (pass == 0) {
          m[0] += w * p[0].y[i], m[1] += w * p[1].y[i], m[2] += w;
          continue;
        }
        a0 += w * std::pow((p[0].y[i] - m[0] / m[2]) / obs.sigma[i], 2);
        a1 += w * std::pow((p[1].y[i] - m[1] / m[2]) / obs.sigma[i], 2);
        nl += w;
      }
    const double nn = std::max(1.0, nl);
    return std::array<double, 2>{std::sqrt(a0 / nn), std::sqrt(a1 / nn)};
  };
  const double t_late = rec.t_begin() + 0.75 * span;
  const auto late = amplitudes(t_late, rec.t_end());
  double excitation = 1;  // the dt/2 run's amplitude over the dt run's, early
  if (!s.release_specs.empty()) {
    const auto early = amplitudes(rec.t_begin(), rec.t_begin() + 0.25 * span);
    if (early[0] > 0 && early[1] > 0) excitation = early[1] / early[0];
  }
  D.numerical_change = p[1].ok ? std::abs(late[0] - late[1] / excitation) : 1e300;
  D.numerical_dispersion = p[1].ok ? late_difference(obs, p[0], p[1], t_late) : 0.0;
  // dt is halved when its amplitude error could pass for an effect. The error at dt is about 4/3 of
  // the dt-to-dt/2 change (second order), and an effect must lower the held-out rms by
  // kMinHeldoutGain: an error of e noise sd on top of the noise can do that only when sqrt(1 + e^2)
  // >= 1 / (1 - kMinHeldoutGain), e >= 0.75 at 20 %, i.e. a measured change of 0.56 sd. Halving
  // below that doubles every run's cost for nothing a verdict can see.
  const double e_max = std::sqrt(std::pow(1.0 / (1.0 - kMinHeldoutGain), 2) - 1.0);
  if (D.numerical_change > 0.75 * e_max) {
    nominal.dt /= 2;
    D.dt_halved = true;
  }
  D.dt = nominal.dt;
  s.nominal_pred = p[0];
  D.rms_nominal = rms(obs, p[0], obs.train);
  D.heldout_rms_nominal = rms(obs, p[0], obs.heldout);
  log::info(
      "numerical check (dt/2 rerun): amplitude change {:.3g} noise sd "
      "(dissipation), "
      "late-time difference {:.3g} noise sd (dispersion){}",
      D.numerical_change, D.numerical_dispersion, D.dt_halved ? "; using dt/2" : "");
}

}  // namespace

State::State(MPI_Comm comm_, const Config& cfg_, const DiagnoseOptions& opt_)
    : comm(comm_), cfg(cfg_), opt(opt_), wall0(std::chrono::steady_clock::now()) {
  rank = parallel::rank(comm);
  size = parallel::size(comm);
}

void State::phase_done(const std::string& name) {
  const auto now = std::chrono::steady_clock::now();
  D.phases.push_back(
      {name, ev->runs() - phase_runs, std::chrono::duration<double>(now - phase_t0).count()});
  phase_runs = ev->runs();
  phase_t0 = now;
}

void observe(State& s) {
  const DiagnoseOptions& opt = s.opt;
  if (opt.recordings.empty()) throw InputError("gen4d diagnose: --recording is required");
  if (!(opt.holdout >= 0 && opt.holdout <= 0.5))
    throw InputError(fmt::format("gen4d diagnose: --holdout {} must be in [0, 0.5]", opt.holdout));
  s.D.deck = s.cfg.source;
  s.D.ranks = s.size;
  s.model = make_forward_model(s.cfg);
  s.D.model = s.model->kind();
  open_library(s);
  s.D.body = s.model->bounds();
  read_observations(s);
  s.phase_t0 = std::chrono::steady_clock::now();
  numerical_check(s);
  s.phase_done("numerical check (dt/2 rerun)");
}

}  // namespace gen4d::diagnose
