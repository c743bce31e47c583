#include "diagnose/Modal.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <utility>

namespace gen4d::diagnose {
namespace {

//! Samples (t, y, 1/sigma) of each channel component after t_from.
struct Series {
  std::vector<double> t, y, w;
};

std::vector<Series> free_series(const Observations& obs, const std::vector<double>& y,
                                double t_from) {
  std::vector<Series> out;
  for (const auto& idx :
       component_series(obs, t_from, true, [&](std::size_t i) { return std::isfinite(y[i]); })) {
    if (idx.size() < 8) continue;
    Series s;
    for (std::size_t i : idx) {
      s.t.push_back(obs.t[i]);
      s.y.push_back(y[i]);
      s.w.push_back(obs.sigma[i] > 0 ? 1 / obs.sigma[i] : 1.0);
    }
    out.push_back(std::move(s));
  }
  return out;
}

double misfit(const std::vector<Series>& ser, const std::vector<double>& omegas) {
  const int m = 1 + 2 * static_cast<int>(omegas.size());
  double total = 0;
  Eigen::MatrixXd AtA(m, m);
  Eigen::VectorXd Aty(m), a(m);
  for (const Series& s : ser) {
    AtA.setZero();
    Aty.setZero();
    double yty = 0;
    for (std::size_t k = 0; k < s.t.size(); ++k) {
      a[0] = s.w[k];
      for (std::size_t q = 0; q < omegas.size(); ++q) {
        const double ph = omegas[q] * s.t[k];
        a[static_cast<Eigen::Index>(1 + 2 * q)] = s.w[k] * std::cos(ph);
        a[static_cast<Eigen::Index>(2 + 2 * q)] = s.w[k] * std::sin(ph);
      }
      const double yk = s.w[k] * s.y[k];
      AtA.selfadjointView<Eigen::Lower>().rankUpdate(a);
      Aty += yk * a;
      yty += yk * yk;
    }
    AtA.triangularView<Eigen::StrictlyUpper>() = AtA.transpose();
    // Nearly equal frequencies make the basis singular: a pseudo-inverse then simply fits
    // what the distinct columns can.
    const Eigen::LDLT<Eigen::MatrixXd> ldlt(AtA);
    double fitted = 0;
    if (ldlt.info() == Eigen::Success && ldlt.isPositive()) {
      const Eigen::VectorXd c = ldlt.solve(Aty);
      fitted = c.dot(Aty);
    }
    total += std::max(0.0, yty - fitted);
  }
  return total;
}

//! Minimum of f over [a, b] by golden sections (f unimodal there).
template <class F>
double golden(F&& f, double a, double b, int iterations) {
  const double g = 0.5 * (std::sqrt(5.0) - 1);
  double c = b - g * (b - a), d = a + g * (b - a), fc = f(c), fd = f(d);
  for (int i = 0; i < iterations; ++i) {
    if (fc < fd)
      b = d, d = c, fd = fc, c = b - g * (b - a), fc = f(c);
    else
      a = c, c = d, fc = fd, d = a + g * (b - a), fd = f(d);
  }
  return fc < fd ? c : d;
}

//! Grid scan of f over [lo, hi] with spacing dw, the best cell refined by golden sections.
template <class F>
double scan(F&& f, double lo, double hi, double dw, double& best) {
  best = 1e300;
  double wb = lo;
  for (double w = lo; w <= hi; w += dw) {
    const double v = f(w);
    if (v < best) best = v, wb = w;
  }
  const double w = golden(f, std::max(lo, wb - dw), std::min(hi, wb + dw), 30);
  const double fw = f(w);
  if (fw > best) return wb;
  best = fw;
  return w;
}

}  // namespace

double sinusoid_misfit(const Observations& obs, const std::vector<double>& y, double t_from,
                       const std::vector<double>& omegas) {
  return misfit(free_series(obs, y, t_from), omegas);
}

ModalFrequencies modal_frequencies(const Observations& obs, const std::vector<double>& y,
                                   double t_from, double omega1_guess, double omega2_guess) {
  ModalFrequencies mf;
  const std::vector<Series> ser = free_series(obs, y, t_from);
  if (ser.empty() || !(omega1_guess > 0)) return mf;
  double t0 = 1e300, t1 = -1e300;
  std::vector<double> spacing;
  for (const Series& s : ser) {
    t0 = std::min(t0, s.t.front());
    t1 = std::max(t1, s.t.back());
    for (std::size_t k = 1; k < s.t.size(); ++k) spacing.push_back(s.t[k] - s.t[k - 1]);
  }
  std::nth_element(spacing.begin(), spacing.begin() + static_cast<long>(spacing.size() / 2),
                   spacing.end());
  const double dt = spacing[spacing.size() / 2], span = t1 - t0;
  if (!(span > 0) || !(dt > 0)) return mf;
  // Frequency resolution of the record: the grid is a quarter of the spacing of independent
  // frequencies (pi / span), the cell's best refined by golden sections.
  const double dw = kPi / (4 * span);
  double best1 = 0;
  const double w1s = scan([&](double w) { return misfit(ser, {w}); }, 0.7 * omega1_guess,
                          1.3 * omega1_guess, dw, best1);
  mf.omega1 = w1s;
  const double w_max = 0.9 * kPi / dt;
  if (!(w_max > 1.5 * w1s)) return mf;
  // omega1 refined with its harmonic first, so that the drop credited to omega2 is its own.
  const double w1 = golden(
      [&](double w) {
        return misfit(ser, {w, 2 * w});
      },
      w1s - dw, w1s + dw, 30);
  const double s0 = misfit(ser, {w1, 2 * w1});
  // Large rotations put harmonics of the first mode into the motion: 2 omega1 (along the
  // axis, in the basis) and 3 omega1 (cubic stiffening); higher ones are negligible, and a
  // mode that happens to lie near one (heterogeneity-soft: omega2 100.4 rad/s, 5 omega1
  // 99.8 rad/s) must not be excluded.
  auto near_harmonic = [&](double w) {
    for (int k = 2; k <= 3; ++k)
      if (std::abs(w - k * w1) < 0.03 * k * w1 + 2 * dw) return true;
    return false;
  };

  double best2 = 1e300, wb = 0;
  const double lo2 = omega2_guess > 0 ? std::max(1.5 * w1, 0.65 * omega2_guess) : 1.5 * w1;
  const double hi2 = omega2_guess > 0 ? std::min(w_max, 1.35 * omega2_guess) : w_max;
  for (double w = lo2; w <= hi2; w += dw) {
    if (near_harmonic(w)) continue;
    const double v = misfit(ser, {w1, 2 * w1, w});
    if (v < best2) best2 = v, wb = w;
  }
  if (wb == 0) return mf;
  // Joint refinement: omega2 in its cell, then omega1 (with its harmonic), then omega2 again.
  double w2 = golden([&](double w) { return misfit(ser, {w1, 2 * w1, w}); }, wb - dw, wb + dw, 30);
  const double w1r = golden(
      [&](double w) {
        return misfit(ser, {w, 2 * w, w2});
      },
      w1 - dw, w1 + dw, 30);
  w2 = golden([&](double w) { return misfit(ser, {w1r, 2 * w1r, w}); }, w2 - dw, w2 + dw, 30);
  const double s2 = misfit(ser, {w1r, 2 * w1r, w2});
  const double m = static_cast<double>(ser.size());
  mf.drop = s0 - s2;
  mf.threshold = 2 * m + 10 * std::sqrt(4 * m) + 25;
  if (mf.drop > mf.threshold) {
    mf.omega1 = w1r;
    mf.omega2 = w2;
  }
  return mf;
}

}  // namespace gen4d::diagnose
