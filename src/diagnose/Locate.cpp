//! Stage locate: when the calibrated deck misses (residual energy per time bin, segmented at change
//! points), where (the markers with the largest error, the stiffness sensitivity of super-voxels
//! and the box of them that explains the most), and the scene scales the effects size their probes
//! by (dominant and modal frequencies, amplitude, mass, area).
#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>

#include "core/Log.hpp"
#include "diagnose/Pipeline.hpp"

namespace gen4d::diagnose {

std::vector<double> bin_energy(const State& s, const Prediction& p) {
  const Observations& obs = s.obs;
  const double tb = s.tb, te = s.te;
  const int nbins = State::kBins;
  std::vector<double> e(nbins, 0.0), n(nbins, 0.0);
  for (std::size_t i = 0; i < obs.size(); ++i) {
    const int b = std::clamp(static_cast<int>((obs.t[i] - tb) / (te - tb) * nbins), 0, nbins - 1);
    e[static_cast<std::size_t>(b)] += std::pow((p.y[i] - obs.y[i]) / obs.sigma[i], 2);
    n[static_cast<std::size_t>(b)] += 1;
  }
  for (int b = 0; b < nbins; ++b)
    e[static_cast<std::size_t>(b)] /= std::max(1.0, n[static_cast<std::size_t>(b)]);
  return e;
}

std::vector<double> channel_rms(const State& st, const Prediction& p) {
  const Observations& obs = st.obs;
  std::vector<double> s(obs.requests.size(), 0.0), n(obs.requests.size(), 0.0);
  for (std::size_t i = 0; i < obs.size(); ++i) {
    s[static_cast<std::size_t>(obs.channel[i])] += std::pow(p.y[i] - obs.y[i], 2);
    n[static_cast<std::size_t>(obs.channel[i])] += 1;
  }
  for (std::size_t c = 0; c < s.size(); ++c) s[c] = std::sqrt(s[c] / std::max(1.0, n[c]));
  return s;
}

Eigen::VectorXd project(const State& s, const Eigen::VectorXd& d) {
  return d - s.Qb * (s.Qb.transpose() * d);
}

namespace {

//! When: the calibrated deck's residual energy per time bin, segmented at change points (binary
//! segmentation of log energy with a BIC-like penalty); the windows whose residual variance exceeds
//! twice the noise, and the load phase each lies in.
void time_windows(State& s) {
  Diagnosis& D = s.D;
  const double tb = s.tb, te = s.te;
  const int nbins = State::kBins;
  const std::vector<double>& events = s.events;
  D.bin_e_before = bin_energy(s, s.base.pred);
  for (int b = 0; b < nbins; ++b) D.bin_t.push_back(tb + (b + 0.5) * (te - tb) / nbins);
  std::vector<double> le;
  for (double e : D.bin_e_before) le.push_back(std::log(std::max(e, 1e-3)));
  std::vector<double> diffs;
  for (std::size_t i = 1; i < le.size(); ++i) diffs.push_back(std::abs(le[i] - le[i - 1]));
  const double s2 = std::pow(median(diffs) / 0.954, 2) / 2 + 1e-6;
  std::vector<std::pair<int, int>> segs = {{0, nbins}}, done;
  while (!segs.empty()) {
    auto [a, b] = segs.back();
    segs.pop_back();
    auto sse = [&](int x, int y) {
      double m = 0;
      for (int i = x; i < y; ++i) m += le[static_cast<std::size_t>(i)];
      m /= (y - x);
      double s = 0;
      for (int i = x; i < y; ++i) s += std::pow(le[static_cast<std::size_t>(i)] - m, 2);
      return s;
    };
    const double whole = sse(a, b);
    double best = 0;
    int split = -1;
    for (int c = a + 2; c <= b - 2; ++c) {
      const double gain = whole - sse(a, c) - sse(c, b);
      if (gain > best) best = gain, split = c;
    }
    if (split > 0 && best > 3 * s2 * std::log(static_cast<double>(nbins))) {
      segs.push_back({a, split});
      segs.push_back({split, b});
    } else {
      done.push_back({a, b});
    }
  }
  std::sort(done.begin(), done.end());
  for (auto [a, b] : done) {
    double m = 0;
    for (int i = a; i < b; ++i) m += D.bin_e_before[static_cast<std::size_t>(i)];
    m /= (b - a);
    if (m < 2.0) continue;  // residual variance within twice the noise
    const double t0 = tb + a * (te - tb) / nbins, t1 = tb + b * (te - tb) / nbins;
    if (!D.time_windows.empty() && std::abs(D.time_windows.back().second - t0) < 1e-12)
      D.time_windows.back().second = t1;
    else
      D.time_windows.push_back({t0, t1});
  }
  for (auto [t0, t1] : D.time_windows) {
    std::string ph;
    double last = 0;
    for (double e : events) {
      if (e > t0 && e < t1) ph += fmt::format("contains the load change at {:g} s; ", e);
      if (e <= t0) last = e;
    }
    if (ph.empty())
      ph = events.empty() ? "constant load"
                          : (last > 0 ? fmt::format("after the load change at {:g} s", last)
                                      : "under the initial load");
    D.window_phase.push_back(ph);
  }
}

//! Where, by marker: each channel's rms error, the three worst markers.
void worst_markers(State& s) {
  Diagnosis& D = s.D;
  const Recording& rec = s.rec;
  D.channel_rms_before = channel_rms(s, s.base.pred);
  for (const Channel& c : rec.channels) D.channel_ids.push_back(c.id), D.channel_X.push_back(c.X);
  {
    std::vector<std::size_t> order(rec.channels.size());
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
      return D.channel_rms_before[a] > D.channel_rms_before[b];
    });
    for (std::size_t i = 0; i < std::min<std::size_t>(3, order.size()); ++i)
      D.markers.push_back(rec.channels[order[i]].id);
  }
}

//! Scene scales for the effects: the dominant and modal frequencies, the continuation windows, the
//! baseline's peak stress and speed, the mass, area, amplitude and lowest marker.
void scene_scales(State& s) {
  const Observations& obs = s.obs;
  const ForwardModel& model = *s.model;
  const Diagnosis& D = s.D;
  const Recording& rec = s.rec;
  const double t_free = s.t_free;
  EffectContext& ctx = s.ctx;
  ModalFrequencies& modes = s.modes;
  ctx.model = &model;
  ctx.base = s.calibrated;
  ctx.omega = dominant_omega(obs, obs.y, t_free);
  s.windows = continuation_windows(obs, t_free, ctx.omega);
  const std::vector<double>& windows = s.windows;
  if (!windows.empty()) {
    std::string ws;
    for (double w : windows) ws += fmt::format(" {:.3g}", w);
    log::info(
        "continuation windows (fits of effects that move a frequency): t "
        "<={} s",
        ws);
  }
  // The recording's two lowest modal frequencies: an effect that moves a frequency (a region's
  // stiffness, a clamp's) moves their ratio, which E cannot (E scales both), so matching the ratio
  // places its start where both modes are in phase.
  modes = modal_frequencies(obs, obs.y, t_free, ctx.omega);
  log::info("modal frequencies after t = {:.3g} s: {:.4g} rad/s{}", t_free, modes.omega1,
            modes.omega2 > 0 ? fmt::format(" and {:.4g} rad/s (ratio {:.4f}; chi2 drop "
                                           "{:.4g}, noise alone {:.3g})",
                                           modes.omega2, modes.omega2 / modes.omega1, modes.drop,
                                           modes.threshold)
                             : fmt::format("; no second mode above the noise (chi2 drop "
                                           "{:.4g}, noise alone {:.3g})",
                                           modes.drop, modes.threshold));
  s.two_modes = modes.omega2 > 0;
  s.r_obs = s.two_modes ? modes.omega2 / modes.omega1 : 0.0;
  ctx.max_mises = s.base.pred.max_mises;
  ctx.max_speed = s.base.pred.max_speed;
  ctx.total_mass = model.volume() * s.calibrated.density;
  ctx.sensors.clear();
  for (const ChannelRequest& r : s.obs.requests)
    if (r.acceleration) ctx.sensors.push_back(r.at.X);
  ctx.surface_area = model.exposed_area();
  double amp = 0, low = 1e300;
  std::map<std::pair<int, int>, std::pair<double, double>> range;
  for (std::size_t i = 0; i < obs.size(); ++i) {
    const int c = obs.channel[i];
    if (obs.requests[static_cast<std::size_t>(c)].acceleration) continue;
    auto it = range.find({c, obs.component[i]});
    if (it == range.end()) it = range.insert({{c, obs.component[i]}, {obs.y[i], obs.y[i]}}).first;
    it->second.first = std::min(it->second.first, obs.y[i]);
    it->second.second = std::max(it->second.second, obs.y[i]);
    if (obs.component[i] == 2)
      low =
          std::min(low, obs.y[i] - (rec.channels[static_cast<std::size_t>(c)].X[2] - D.body.lo[2]));
  }
  for (auto& [k, r] : range) amp = std::max(amp, 0.5 * (r.second - r.first));
  ctx.amplitude = amp;
  ctx.lowest_point = low < 1e299 ? low : D.body.lo[2];
}

//! The box of super-voxels (keys, indices into dp by key) whose joint softening explains the most
//! of the residual r0 (linearised: the sum of its blocks' directions, best scaling), as {x0, y0,
//! z0, x1, y1, z1}; g: the chi-square it explains.
std::array<long, 6> best_block_box(const std::vector<std::array<long, 3>>& keys,
                                   const std::vector<Eigen::VectorXd>& dp,
                                   const Eigen::VectorXd& r0, double& g) {
  std::array<long, 3> nbk{0, 0, 0};
  for (const auto& k : keys)
    for (int a = 0; a < 3; ++a) nbk[a] = std::max(nbk[a], k[a] + 1);
  std::map<std::array<long, 3>, std::size_t> index;
  for (std::size_t i = 0; i < keys.size(); ++i) index[keys[i]] = i;
  g = -1;
  std::array<long, 6> best_box{0, 0, 0, 1, 1, 1};
  for (long x0 = 0; x0 < nbk[0]; ++x0)
    for (long x1 = x0 + 1; x1 <= nbk[0]; ++x1)
      for (long y0 = 0; y0 < nbk[1]; ++y0)
        for (long y1 = y0 + 1; y1 <= nbk[1]; ++y1)
          for (long z0 = 0; z0 < nbk[2]; ++z0)
            for (long z1 = z0 + 1; z1 <= nbk[2]; ++z1) {
              Eigen::VectorXd col = Eigen::VectorXd::Zero(r0.size());
              for (long x = x0; x < x1; ++x)
                for (long y = y0; y < y1; ++y)
                  for (long z = z0; z < z1; ++z) {
                    const auto it = index.find({x, y, z});
                    if (it != index.end()) col += dp[it->second];
                  }
              const double nn = col.squaredNorm();
              const double gi = nn > 0 ? std::pow(col.dot(r0), 2) / nn : 0.0;
              if (gi > g * 1.001) g = gi, best_box = {x0, y0, z0, x1, y1, z1};
            }
  return best_box;
}

//! Where, in the material: the sensitivity of the residual to the stiffness of super-voxels (at
//! most 40 blocks of b^3 voxels, each softened to 0.8), and the box of them that explains the most
//! (the located region).
void stiffness_map(State& s) {
  const Observations& obs = s.obs;
  const ForwardModel& model = *s.model;
  Diagnosis& D = s.D;
  EffectContext& ctx = s.ctx;
  const double chi2_0 = s.chi2_0;
  const Eigen::VectorXd& r0 = s.base.r;
  int b = 1;
  std::array<long, 3> lo{1L << 40, 1L << 40, 1L << 40}, hi{0, 0, 0};
  for (std::size_t v = 0; v < model.voxels(); ++v)
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], model.voxel_ijk(v)[a]);
      hi[a] = std::max(hi[a], model.voxel_ijk(v)[a]);
    }
  std::map<std::array<long, 3>, std::vector<std::size_t>> blocks;
  for (;; ++b) {
    blocks.clear();
    for (std::size_t v = 0; v < model.voxels(); ++v) {
      std::array<long, 3> key;
      for (int a = 0; a < 3; ++a) key[a] = (model.voxel_ijk(v)[a] - lo[a]) / b;
      blocks[key].push_back(v);
    }
    if (blocks.size() <= 40) break;
  }
  std::vector<std::array<long, 3>> keys;
  std::vector<Physics> batch;
  for (auto& [key, vox] : blocks) {
    keys.push_back(key);
    Physics p = s.calibrated;
    const BoxRegion b = model.voxel_box(vox);
    set_effect_terms(p, "heterogeneity",
                     {0.8, b.lo[0], b.lo[1], b.lo[2], b.hi[0], b.hi[1], b.hi[2]});
    batch.push_back(p);
  }
  const auto preds = s.ev->run(batch);
  std::vector<Eigen::VectorXd> dp(keys.size());
  std::vector<double> gain(keys.size(), 0.0);
  for (std::size_t i = 0; i < keys.size(); ++i) {
    dp[i] = project(s, weighted_residual(obs, preds[i], obs.train) - r0);
    const double nn = dp[i].squaredNorm();
    gain[i] = nn > 0 ? std::pow(dp[i].dot(r0), 2) / nn : 0.0;
    Vec3d c{0, 0, 0};
    const BoxRegion bx = model.voxel_box(blocks[keys[i]]);
    for (int a = 0; a < 3; ++a) c[a] = 0.5 * (bx.lo[a] + bx.hi[a]);
    D.block_center.push_back(c);
    D.block_gain.push_back(gain[i] / std::max(chi2_0, 1e-300));
  }
  double g = -1;
  const std::array<long, 6> best_box = best_block_box(keys, dp, r0, g);
  std::vector<char> in(keys.size(), 0);
  for (std::size_t i = 0; i < keys.size(); ++i) {
    bool inside = true;
    for (int a = 0; a < 3; ++a)
      inside = inside && keys[i][a] >= best_box[a] && keys[i][a] < best_box[3 + a];
    in[i] = inside;
  }
  std::vector<std::size_t> vox;
  for (std::size_t i = 0; i < keys.size(); ++i)
    if (in[i]) vox.insert(vox.end(), blocks[keys[i]].begin(), blocks[keys[i]].end());
  D.located_region = model.voxel_box(vox);
  D.located = true;
  s.region_share = g / std::max(chi2_0, 1e-300);
  ctx.has_region = true;
  ctx.region = D.located_region;
  log::info(
      "stiffness sensitivity over {} super-voxels ({}^3 voxels): region "
      "[{:.3g} {:.3g} "
      "{:.3g}]-[{:.3g} {:.3g} {:.3g}] explains {:.1f} % of chi2 (linearised)",
      keys.size(), b, ctx.region.lo[0], ctx.region.lo[1], ctx.region.lo[2], ctx.region.hi[0],
      ctx.region.hi[1], ctx.region.hi[2], 100 * g / chi2_0);
}

}  // namespace

void locate(State& s) {
  s.tb = s.rec.t_begin();
  s.te = s.rec.t_end();
  time_windows(s);
  worst_markers(s);
  scene_scales(s);
  const Eigen::MatrixXd& Jb = s.base.J;
  {
    Eigen::HouseholderQR<Eigen::MatrixXd> qr(Jb);
    s.Qb = qr.householderQ() * Eigen::MatrixXd::Identity(Jb.rows(), Jb.cols());
  }
  const bool want_region = std::any_of(s.library.begin(), s.library.end(), [](const Effect* e) {
    return e->name() == "heterogeneity";
  });
  if (want_region) stiffness_map(s);
  s.phase_done("stiffness map");
}

}  // namespace gen4d::diagnose
