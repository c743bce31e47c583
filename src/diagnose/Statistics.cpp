//! Statistics and signal measures shared by the diagnose stages (declared in Pipeline.hpp).
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "diagnose/Pipeline.hpp"

namespace gen4d::diagnose {

double chi2_crit999(int k) {
  static const double q[] = {0,     10.83, 13.82, 16.27, 18.47, 20.52,
                             22.46, 24.32, 26.12, 27.88, 29.59};
  if (k >= 1 && k <= 10) return q[k];
  const double z = 3.0902, a = 2.0 / (9.0 * k);
  return k * std::pow(1 - a + z * std::sqrt(a), 3);
}

double chi2_tail(double x, double k) {
  if (k <= 0) return 1;
  const double a = 2.0 / (9.0 * k);
  const double z = (std::cbrt(x / k) - (1 - a)) / std::sqrt(a);
  return 0.5 * std::erfc(z / std::sqrt(2.0));
}

double median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  const std::size_t m = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(m), v.end());
  return v[m];
}

double to_z(const ParamSpec& s, double v) {
  return s.log ? std::log(std::max(v, 1e-300)) : v / s.scale;
}
double from_z(const ParamSpec& s, double z) {
  return s.log ? std::exp(z) : z * s.scale;
}

double late_difference(const Observations& obs, const Prediction& a, const Prediction& b,
                       double t_late) {
  double d2 = 0;
  long nl = 0;
  for (std::size_t i = 0; i < obs.size(); ++i)
    if (obs.t[i] >= t_late) {
      const double r = (a.y[i] - b.y[i]) / obs.sigma[i];
      d2 += r * r;
      ++nl;
    }
  return std::sqrt(d2 / static_cast<double>(std::max(1L, nl)));
}

void whiteness(const Observations& obs, const Prediction& p, double& p_value, double& lag1) {
  const int lags = 10;
  double Q = 0, dof = 0, r1 = 0;
  long series = 0;
  for (const auto& idx : component_series(obs)) {
    std::vector<double> r(idx.size());
    for (std::size_t k = 0; k < idx.size(); ++k)
      r[k] = (p.y[idx[k]] - obs.y[idx[k]]) / obs.sigma[idx[k]];
    const std::size_t n = r.size();
    if (n < 3 * lags) continue;
    const double m = std::accumulate(r.begin(), r.end(), 0.0) / static_cast<double>(n);
    double c0 = 0;
    for (double x : r) c0 += (x - m) * (x - m);
    if (c0 <= 0) continue;
    for (int k = 1; k <= lags; ++k) {
      double ck = 0;
      for (std::size_t i = static_cast<std::size_t>(k); i < n; ++i)
        ck += (r[i] - m) * (r[i - k] - m);
      const double rho = ck / c0;
      if (k == 1) r1 += rho;
      Q += static_cast<double>(n) * (static_cast<double>(n) + 2) * rho * rho /
           static_cast<double>(n - static_cast<std::size_t>(k));
    }
    dof += lags;
    ++series;
  }
  p_value = series ? chi2_tail(Q, dof) : 1.0;
  lag1 = series ? r1 / static_cast<double>(series) : 0.0;
}

double dominant_omega(const Observations& obs, const std::vector<double>& y, double t_from) {
  double best_var = -1, omega = 2 * kPi;
  for (const auto& idx : component_series(obs, t_from, true)) {
    std::vector<std::pair<double, double>> s(idx.size());
    for (std::size_t k = 0; k < idx.size(); ++k) s[k] = {obs.t[idx[k]], y[idx[k]]};
    if (s.size() < 8) continue;
    double m = 0;
    for (auto& [t, y] : s) m += y;
    m /= static_cast<double>(s.size());
    double var = 0;
    for (auto& [t, y] : s) var += (y - m) * (y - m);
    if (var <= best_var) continue;
    // Crossings of a 3-point smoothed signal so noise does not add crossings.
    std::vector<double> sm(s.size());
    for (std::size_t i = 0; i < s.size(); ++i) {
      const std::size_t a = i ? i - 1 : i, b = std::min(i + 1, s.size() - 1);
      sm[i] = (s[a].second + s[i].second + s[b].second) / 3 - m;
    }
    double first = -1, last = -1;
    int n = 0;
    for (std::size_t i = 1; i < sm.size(); ++i)
      if ((sm[i - 1] < 0) != (sm[i] < 0)) {
        const double tc = s[i].first;
        if (first < 0) first = tc;
        if (last >= 0 && tc - last < 0.2 * (tc - first) / std::max(n, 1)) continue;
        last = tc;
        ++n;
      }
    if (n >= 3) {
      best_var = var;
      omega = kPi * (n - 1) / (last - first);
    }
  }
  return omega;
}

Vec3d motion_direction(const Observations& obs, double t_from) {
  double best_var = -1;
  int axis = 2;
  for (const auto& idx : component_series(obs, t_from, true)) {
    if (idx.empty()) continue;
    double m = 0, var = 0;
    for (std::size_t i : idx) m += obs.y[i];
    m /= static_cast<double>(idx.size());
    for (std::size_t i : idx) var += (obs.y[i] - m) * (obs.y[i] - m);
    if (var > best_var) best_var = var, axis = obs.component[idx.front()];
  }
  Vec3d d{0, 0, 0};
  d[static_cast<std::size_t>(axis)] = 1;
  return d;
}

std::vector<Crossing> ratio_crossings(std::vector<ModePoint> pts, double r_target) {
  std::sort(pts.begin(), pts.end(),
            [](const ModePoint& a, const ModePoint& b) { return a.zp < b.zp; });
  std::vector<Crossing> out;
  auto along = [](const ModePoint& a, const ModePoint& b, double zp) {
    Crossing x;
    x.slope_r = (b.ratio - a.ratio) / (b.zp - a.zp);
    x.slope_w = (b.log_w1 - a.log_w1) / (b.zp - a.zp);
    x.zp = zp;
    x.log_w1 = a.log_w1 + x.slope_w * (zp - a.zp);
    return x;
  };
  for (std::size_t j = 0; j + 1 < pts.size(); ++j) {
    const double d0 = pts[j].ratio - r_target, d1 = pts[j + 1].ratio - r_target;
    if ((d0 <= 0) != (d1 <= 0) && pts[j + 1].zp > pts[j].zp)
      out.push_back(
          along(pts[j], pts[j + 1], pts[j].zp + d0 / (d0 - d1) * (pts[j + 1].zp - pts[j].zp)));
  }
  if (out.empty() && pts.size() >= 2) {
    const bool high = std::abs(pts.back().ratio - r_target) < std::abs(pts[0].ratio - r_target);
    const ModePoint& end = high ? pts.back() : pts[0];
    const ModePoint& next = high ? pts[pts.size() - 2] : pts[1];
    const double step = end.zp - next.zp, slope = (end.ratio - next.ratio) / step;
    if (slope != 0 && std::isfinite(slope)) {
      const double dz = (r_target - end.ratio) / slope;
      if (dz * step > 0)
        out.push_back(
            along(next, end, end.zp + std::copysign(std::min(std::abs(dz), std::abs(step)), step)));
    }
  }
  return out;
}

double vuong_z(const Observations& obs, const std::vector<char>& mask, const Prediction& a,
               const Prediction& b) {
  if (!a.ok || !b.ok) return a.ok ? 1e300 : -1e300;
  std::vector<double> batch;
  for (const auto& d : component_series(obs, -std::numeric_limits<double>::infinity(), false,
                                        [&](std::size_t i) { return mask[i] != 0; }))
    for (std::size_t k = 0; k < d.size(); k += 10) {
      double acc = 0;
      for (std::size_t j = k; j < std::min(d.size(), k + 10); ++j) {
        const std::size_t i = d[j];
        const double ra = (a.y[i] - obs.y[i]) / obs.sigma[i];
        const double rb = (b.y[i] - obs.y[i]) / obs.sigma[i];
        acc += rb * rb - ra * ra;
      }
      batch.push_back(acc);
    }
  if (batch.size() < 2) return 0;
  double sum = 0, sum2 = 0;
  for (double x : batch) sum += x, sum2 += x * x;
  const double n = static_cast<double>(batch.size());
  const double var = std::max(sum2 / n - (sum / n) * (sum / n), 1e-300) * n / (n - 1);
  return sum / std::sqrt(n * var);
}

void residual_noise(const Observations& obs, const Prediction& p, double& res_pos,
                    double& res_acc) {
  // Each channel's residual as a recording (the values of obs run channel by channel, sample by
  // sample, component by component; a sample's time is new, and only its measured values are).
  std::vector<Channel> res;
  for (std::size_t i = 0; i < obs.size(); ++i) {
    const auto c = static_cast<std::size_t>(obs.channel[i]);
    if (res.size() <= c) res.resize(c + 1);
    Channel& ch = res[c];
    ch.kind = obs.requests[c].acceleration ? ChannelKind::Acceleration : ChannelKind::Position;
    if (ch.t.empty() || obs.t[i] != ch.t.back()) {
      ch.t.push_back(obs.t[i]);
      ch.value.push_back({0, 0, 0});
      ch.measured.push_back({false, false, false});
    }
    ch.value.back()[static_cast<std::size_t>(obs.component[i])] = obs.y[i] - p.y[i];
    ch.measured.back()[static_cast<std::size_t>(obs.component[i])] = true;
  }
  std::vector<const Channel*> pos, acc;
  for (const Channel& c : res) (c.kind == ChannelKind::Position ? pos : acc).push_back(&c);
  res_pos = estimate_noise(pos);
  res_acc = estimate_noise(acc);
}

}  // namespace gen4d::diagnose
