#include "forward/Filter.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace gen4d::forward {

namespace {

//! y = b0 x + b1 x1 + b2 x2 - a1 y1 - a2 y2 (direct form I).
struct Biquad {
  double b0 = 1, b1 = 0, b2 = 0, a1 = 0, a2 = 0;
  void run(std::vector<double>& v) const {
    // Started at rest on the first value (its steady state: the DC gain is 1).
    double x1 = v.front(), x2 = v.front(), y1 = v.front(), y2 = v.front();
    for (double& x : v) {
      const double y = b0 * x + b1 * x1 + b2 * x2 - a1 * y1 - a2 * y2;
      x2 = x1, x1 = x, y2 = y1, y1 = y;
      x = y;
    }
  }
};

//! The two sections of the 4th-order Butterworth low-pass (poles at angles 3pi/8, pi/8 from
//! the imaginary axis: quality factors 1 / (2 cos(pi/8)) and 1 / (2 cos(3pi/8))).
std::array<Biquad, 2> butterworth4(double dt, double cutoff_hz) {
  const double pi = std::acos(-1.0);
  const double k = std::tan(pi * cutoff_hz * dt);  // prewarped
  std::array<Biquad, 2> s;
  const double q[2] = {1.0 / (2 * std::cos(pi / 8)), 1.0 / (2 * std::cos(3 * pi / 8))};
  for (int i = 0; i < 2; ++i) {
    const double norm = 1.0 / (1 + k / q[i] + k * k);
    s[i].b0 = k * k * norm;
    s[i].b1 = 2 * s[i].b0;
    s[i].b2 = s[i].b0;
    s[i].a1 = 2 * (k * k - 1) * norm;
    s[i].a2 = (1 - k / q[i] + k * k) * norm;
  }
  return s;
}

}  // namespace

void lowpass_zero_phase(double* x, std::size_t n, std::size_t stride, double dt, double cutoff_hz) {
  if (n < 3 || !(dt > 0) || !(cutoff_hz > 0) || cutoff_hz * dt >= 0.5) return;
  const std::size_t pad =
      std::min(n - 1, static_cast<std::size_t>(std::ceil(3.0 / (cutoff_hz * dt))));
  std::vector<double> v(n + 2 * pad);
  for (std::size_t i = 0; i < n; ++i) v[pad + i] = x[i * stride];
  for (std::size_t i = 1; i <= pad; ++i) {
    v[pad - i] = 2 * x[0] - x[i * stride];
    v[pad + n - 1 + i] = 2 * x[(n - 1) * stride] - x[(n - 1 - i) * stride];
  }
  const auto sections = butterworth4(dt, cutoff_hz);
  for (const Biquad& b : sections) b.run(v);
  std::reverse(v.begin(), v.end());
  for (const Biquad& b : sections) b.run(v);
  std::reverse(v.begin(), v.end());
  for (std::size_t i = 0; i < n; ++i) x[i * stride] = v[pad + i];
}

}  // namespace gen4d::forward
