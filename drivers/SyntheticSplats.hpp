//! Synthetic Gaussian splats for the drivers and the renderer's tests: random anisotropic
//! covariances and two SH-degree-3 objects (an ellipsoidal shell and a torus-knot tube) whose
//! splats are flattened along the surface and carry strong view-dependent harmonics.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <random>
#include <vector>

#include "gaussians/Splats.hpp"

namespace gen4d::synthetic {

//! A unit quaternion (w, x, y, z) from four uniform draws in [-1, 1], normalised.
template <class Rng>
std::array<double, 4> random_quaternion(Rng& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  std::array<double, 4> q;
  for (double& v : q) v = u(rng);
  const double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  for (double& v : q) v /= n;
  return q;
}

//! The rotation matrix (row-major) of a unit quaternion (w, x, y, z).
inline std::array<double, 9> quaternion_matrix(const std::array<double, 4>& q) {
  const double w = q[0], x = q[1], y = q[2], z = q[3];
  return {1 - 2 * (y * y + z * z), 2 * (x * y - w * z),     2 * (x * z + w * y),
          2 * (x * y + w * z),     1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
          2 * (x * z - w * y),     2 * (y * z + w * x),     1 - 2 * (x * x + y * y)};
}

//! A unit quaternion (w, x, y, z) of the rotation whose columns are the orthonormal,
//! right-handed axes `a`, `b`, `c` (Shepperd's method).
inline std::array<double, 4> axes_quaternion(const std::array<double, 3>& a,
                                             const std::array<double, 3>& b,
                                             const std::array<double, 3>& c) {
  const double m00 = a[0], m01 = b[0], m02 = c[0], m10 = a[1], m11 = b[1], m12 = c[1], m20 = a[2],
               m21 = b[2], m22 = c[2];
  const double tr = m00 + m11 + m22;
  std::array<double, 4> q;
  if (tr > 0) {
    const double s = 2 * std::sqrt(1 + tr);
    q = {s / 4, (m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s};
  } else if (m00 > m11 && m00 > m22) {
    const double s = 2 * std::sqrt(1 + m00 - m11 - m22);
    q = {(m21 - m12) / s, s / 4, (m01 + m10) / s, (m02 + m20) / s};
  } else if (m11 > m22) {
    const double s = 2 * std::sqrt(1 + m11 - m00 - m22);
    q = {(m02 - m20) / s, (m01 + m10) / s, s / 4, (m12 + m21) / s};
  } else {
    const double s = 2 * std::sqrt(1 + m22 - m00 - m11);
    q = {(m10 - m01) / s, (m02 + m20) / s, (m12 + m21) / s, s / 4};
  }
  return q;
}

//! R diag(s^2) R^T as an upper triangle (xx, xy, xz, yy, yz, zz).
inline std::array<double, 6> covariance(const std::array<double, 4>& q,
                                        const std::array<double, 3>& s) {
  const std::array<double, 9> R = quaternion_matrix(q);
  const int idx[6][2] = {{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}};
  std::array<double, 6> c;
  for (int e = 0; e < 6; ++e) {
    double v = 0;
    for (int k = 0; k < 3; ++k) v += R[3 * idx[e][0] + k] * s[k] * s[k] * R[3 * idx[e][1] + k];
    c[e] = v;
  }
  return c;
}

//! A random covariance R diag(s^2) R^T: R from random_quaternion, then three standard
//! deviations uniform in [lo, hi], drawn in that order.
template <class Rng>
std::array<double, 6> random_covariance(Rng& rng, double lo, double hi) {
  const std::array<double, 4> q = random_quaternion(rng);
  std::uniform_real_distribution<double> u(lo, hi);
  std::array<double, 3> s;
  for (double& v : s) v = u(rng);
  return covariance(q, s);
}

namespace detail {

inline std::array<double, 3> normalized(const std::array<double, 3>& v) {
  const double n = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  return {v[0] / n, v[1] / n, v[2] / n};
}
inline std::array<double, 3> cross(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

//! Random harmonics that vary smoothly over the object: each of the 48 coefficients (SH 3,
//! three channels) is a sum of two plane waves of random direction, wavenumber in [2, 5] per
//! unit length and phase, plus 20 % per-splat noise; the DC terms span about [-1.5, 1.5], band l
//! has amplitude `amp / l`. Neighbouring splats thus look alike, as in a trained object.
struct SmoothHarmonics {
  std::array<std::array<double, 4>, 96> waves;  //!< per coefficient and wave: k (3), phase
  double amp = 0.6;

  template <class Rng>
  SmoothHarmonics(Rng& rng, double amplitude) : amp(amplitude) {
    std::normal_distribution<double> g(0, 1);
    std::uniform_real_distribution<double> k(2, 5), ph(0, 2 * M_PI);
    for (auto& w : waves) {
      const std::array<double, 3> d = normalized({g(rng), g(rng), g(rng)});
      const double kk = k(rng);
      w = {kk * d[0], kk * d[1], kk * d[2], ph(rng)};
    }
  }
  //! Appends the 48 coefficients at `p`.
  template <class Rng>
  void append(std::vector<double>& sh, Rng& rng, const std::array<double, 3>& p) const {
    std::uniform_real_distribution<double> u(-1, 1);
    for (int k = 0; k < 16; ++k)
      for (int ch = 0; ch < 3; ++ch) {
        const int band = k == 0 ? 0 : k < 4 ? 1 : k < 9 ? 2 : 3;
        double v = 0.2 * u(rng);
        for (int j = 0; j < 2; ++j) {
          const auto& w = waves[2 * (3 * k + ch) + j];
          v += 0.8 / std::sqrt(2.0) * std::sin(w[0] * p[0] + w[1] * p[1] + w[2] * p[2] + w[3]);
        }
        sh.push_back(band == 0 ? 1.5 * v : amp * v / band);
      }
  }
};

//! Appends a splat at `p` flattened on the surface of unit normal `n`: standard deviations
//! `t1`, `t2` along the tangent `tangent` (projected on the plane) and its normal-cross, and
//! `tn` along `n`; random opacity in [0.5, 0.95], harmonics from `sh`.
template <class Rng>
void append_surface_splat(gaussians::SplatSet& s, Rng& rng, const std::array<double, 3>& p,
                          const std::array<double, 3>& n, const std::array<double, 3>& tangent,
                          double t1, double t2, double tn, const SmoothHarmonics& sh) {
  std::uniform_real_distribution<double> o(0.5, 0.95);
  const std::array<double, 3> c = normalized(n);
  const double d = tangent[0] * c[0] + tangent[1] * c[1] + tangent[2] * c[2];
  const std::array<double, 3> a =
      normalized({tangent[0] - d * c[0], tangent[1] - d * c[1], tangent[2] - d * c[2]});
  const std::array<double, 3> b = cross(c, a);
  const std::array<double, 4> q = axes_quaternion(a, b, c);
  s.position.insert(s.position.end(), p.begin(), p.end());
  s.scale.insert(s.scale.end(), {t1, t2, tn});
  s.rotation.insert(s.rotation.end(), q.begin(), q.end());
  s.opacity.push_back(o(rng));
  sh.append(s.sh, rng, p);
}

}  // namespace detail

//! `n` splats on the ellipsoid x^2/1 + y^2/0.55^2 + z^2/0.35^2 = 1 (centre at the origin),
//! each flattened on the surface (tangent deviations 0.6 to 1.4 times the mean spacing, normal
//! deviation 0.15 times it), random opacity in [0.5, 0.95] and SH degree 3 harmonics varying
//! smoothly over the surface (detail::SmoothHarmonics, band l of amplitude `amp / l`).
//! Deterministic in `seed`.
inline gaussians::SplatSet ellipsoid_shell(int n, unsigned seed, double amp = 0.6) {
  gaussians::SplatSet s;
  s.sh_degree = 3;
  std::mt19937_64 rng(seed);
  const detail::SmoothHarmonics harmonics(rng, amp);
  std::normal_distribution<double> g(0, 1);
  std::uniform_real_distribution<double> w(0.6, 1.4);
  const double ax[3] = {1.0, 0.55, 0.35};
  const double area = 4 * M_PI *
                      std::pow((std::pow(ax[0] * ax[1], 1.6) + std::pow(ax[0] * ax[2], 1.6) +
                                std::pow(ax[1] * ax[2], 1.6)) /
                                   3,
                               1 / 1.6);  // Knud Thomsen's approximation
  const double h = std::sqrt(area / n);
  for (int i = 0; i < n; ++i) {
    const std::array<double, 3> d = detail::normalized({g(rng), g(rng), g(rng)});
    const std::array<double, 3> p = {ax[0] * d[0], ax[1] * d[1], ax[2] * d[2]};
    const std::array<double, 3> nrm = {p[0] / (ax[0] * ax[0]), p[1] / (ax[1] * ax[1]),
                                       p[2] / (ax[2] * ax[2])};
    const std::array<double, 3> t = {g(rng), g(rng), g(rng)};
    const double t1 = w(rng) * h, t2 = w(rng) * h;
    detail::append_surface_splat(s, rng, p, nrm, t, t1, t2, 0.15 * h, harmonics);
  }
  return s;
}

//! `n` splats on a tube of radius 0.12 around the (2, 3) torus knot
//! ((0.7 + 0.3 cos 3t) cos 2t, (0.7 + 0.3 cos 3t) sin 2t, 0.3 sin 3t), elongated along the
//! knot (deviation 2.5 times the mean spacing), 0.8 times it around the tube and 0.15 times it
//! along the tube's normal; opacity and harmonics as ellipsoid_shell. Deterministic in `seed`.
inline gaussians::SplatSet torus_knot(int n, unsigned seed, double amp = 0.6) {
  gaussians::SplatSet s;
  s.sh_degree = 3;
  std::mt19937_64 rng(seed);
  const detail::SmoothHarmonics harmonics(rng, amp);
  std::uniform_real_distribution<double> u(0, 1), w(0.8, 1.2);
  const double tube = 0.12;
  auto curve = [](double t) -> std::array<double, 3> {
    const double r = 0.7 + 0.3 * std::cos(3 * t);
    return {r * std::cos(2 * t), r * std::sin(2 * t), 0.3 * std::sin(3 * t)};
  };
  double length = 0;
  for (int k = 0; k < 1000; ++k) {
    const auto a = curve(2 * M_PI * k / 1000), b = curve(2 * M_PI * (k + 1) / 1000);
    length += std::sqrt((b[0] - a[0]) * (b[0] - a[0]) + (b[1] - a[1]) * (b[1] - a[1]) +
                        (b[2] - a[2]) * (b[2] - a[2]));
  }
  const double h = std::sqrt(length * 2 * M_PI * tube / n);
  for (int i = 0; i < n; ++i) {
    const double t = 2 * M_PI * u(rng), phi = 2 * M_PI * u(rng);
    const auto c = curve(t), c1 = curve(t + 1e-4), c0 = curve(t - 1e-4);
    const std::array<double, 3> T =
        detail::normalized({c1[0] - c0[0], c1[1] - c0[1], c1[2] - c0[2]});
    // A frame around the tube: N1 perpendicular to T and z (or x where T is vertical), N2 = T x N1.
    std::array<double, 3> N1 = detail::cross(T, {0, 0, 1});
    if (N1[0] * N1[0] + N1[1] * N1[1] + N1[2] * N1[2] < 1e-6) N1 = detail::cross(T, {1, 0, 0});
    N1 = detail::normalized(N1);
    const std::array<double, 3> N2 = detail::cross(T, N1);
    std::array<double, 3> nrm, p;
    for (int d = 0; d < 3; ++d) {
      nrm[d] = std::cos(phi) * N1[d] + std::sin(phi) * N2[d];
      p[d] = c[d] + tube * nrm[d];
    }
    const double t1 = 2.5 * w(rng) * h, t2 = 0.8 * w(rng) * h;
    detail::append_surface_splat(s, rng, p, nrm, T, t1, t2, 0.15 * h, harmonics);
  }
  return s;
}

}  // namespace gen4d::synthetic
