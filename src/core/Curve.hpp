//! Load curves of a deck ([[curve]]): a named piecewise-linear time factor.
#pragma once

#include <algorithm>
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

namespace gen4d {

//! Piecewise-linear factor through the points (time[i], factor[i]), times strictly
//! increasing; before the first point and after the last it holds the end values. An empty
//! curve (no points) is the constant 1, what a load without `curve` uses.
class Curve {
 public:
  Curve() = default;
  Curve(std::string name, std::vector<double> time, std::vector<double> factor)
      : name_(std::move(name)), t_(std::move(time)), f_(std::move(factor)) {}

  const std::string& name() const { return name_; }
  bool empty() const { return t_.empty(); }
  const std::vector<double>& times() const { return t_; }
  const std::vector<double>& factors() const { return f_; }

  //! The factor at time t.
  double operator()(double t) const {
    if (t_.empty()) return 1.0;
    if (t <= t_.front()) return f_.front();
    if (t >= t_.back()) return f_.back();
    const std::size_t i = segment(t);
    const double s = (t - t_[i]) / (t_[i + 1] - t_[i]);
    return f_[i] + s * (f_[i + 1] - f_[i]);
  }

  //! The integral of the factor over [a, b] (a <= b), exact for the piecewise-linear curve;
  //! b - a for the empty curve.
  double integral(double a, double b) const {
    if (t_.empty()) return b - a;
    if (!(b > a)) return 0.0;
    double sum = 0;
    // Before the first point and after the last the factor is constant.
    if (a < t_.front()) sum += (std::min(b, t_.front()) - a) * f_.front();
    if (b > t_.back()) sum += (b - std::max(a, t_.back())) * f_.back();
    for (std::size_t i = 0; i + 1 < t_.size(); ++i) {
      const double lo = std::max(a, t_[i]), hi = std::min(b, t_[i + 1]);
      if (!(hi > lo)) continue;
      sum += 0.5 * (hi - lo) * ((*this)(lo) + (*this)(hi));
    }
    return sum;
  }

 private:
  //! Index i with t_[i] <= t < t_[i + 1], for t inside (front, back).
  std::size_t segment(double t) const {
    const auto it = std::upper_bound(t_.begin(), t_.end(), t);
    return static_cast<std::size_t>(it - t_.begin()) - 1;
  }

  std::string name_;
  std::vector<double> t_, f_;
};

}  // namespace gen4d
