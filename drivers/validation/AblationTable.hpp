//! The seed's ablation study (PhysGaussian §4.2, Table 1) without Blender: a ground truth made by
//! subdividing every Gaussian into many small ones, deformed by a known smooth map, against the
//! full kinematics and its three ablations applied to the original Gaussians.
//
// Ground truth. In screen space a Gaussian of opacity o adds alpha = o g (g its 2D Gaussian,
// peak 1), i.e. the optical depth -ln(1 - o g) = sum_n (o^n / n) g^n, and g^n is the 2D
// Gaussian of the 3D covariance S / n (S = M M^T, M = R diag(scale)) in every view. Each
// Gaussian (mean mu, opacity o, harmonics C) is replaced by N groups n = 1..N of K small ones:
// covariance alpha^2 S, centres mu + sqrt(1 / n - alpha^2) M w_k, where the w_k are K / 2
// standard normal draws and their negatives, whitened (w <- L^-1 w, L L^T their second moment)
// so that each group's centres have exactly mean mu and covariance (1 / n - alpha^2) S. A small
// one's 2D area is alpha^2 / (1 / n) that of g^n, so group n adds the depth c_n g^n when each
// small one has peak depth d_n = c_n / (K alpha^2 n), with c_n = o^n / n and the last group
// taking the rest of the series, so the depth at the centre is exactly -ln(1 - o). A small one
// of peak depth d composes as 1 - exp(-d g); its opacity is Ein(d) = int_0^1 (1 - exp(-d g))
// dg / g, which keeps its summed alpha over the plane (the area where g > t grows as -ln t).
// Each small one keeps C. The rest images of the subdivided and the original object are
// compared (rest PSNR): that residual bounds what the table can resolve. It does not vanish as
// alpha -> 0: the renderer composites splats in the order of their centres' depths, and the
// small ones of overlapping parents interleave; a fine truth also fades each small one below the
// 1/255 alpha cut-off.
//
// The deformed truth moves every small Gaussian with the map phi and its own gradient at its own
// centre (covariance F alpha^2 S F^T, harmonics evaluated at R^T d): the full kinematics at a
// fine scale, which tends to the exactly deformed density (each small one's peak kept, so the
// optical density is advected) as alpha -> 0. The four methods move the original Gaussians with
// phi and grad phi at their means. An affine phi makes the full method exact; the bend and the
// twist below are not affine over a Gaussian's extent, so the full method differs from the truth
// by a second-order term, the ablations by a first-order one.
#pragma once

#include <mpi.h>

#include <Eigen/Dense>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "gaussians/Camera.hpp"
#include "gaussians/Kinematics.hpp"
#include "gaussians/Render.hpp"
#include "gaussians/Splats.hpp"
#include "SplatBlock.hpp"

namespace gen4d::ablation {

//! The four methods of the seed's Table 1, in its column order.
inline const char* const kMethods[] = {"full", "fixed_covariance", "rigid_covariance",
                                       "fixed_harmonics"};

//! A smooth deformation in the frame of an object: centre c and orthonormal axes e0 (the
//! object's longest extent), e1, e2 = e0 x e1; local coordinates u_a = e_a . (X - c).
//! Bend: the e0 axis bent into an arc of curvature `rate` toward e2 (u0 -> angle rate u0 on
//! the circle of radius 1 / rate; lengths along e0 scale by 1 - rate u2). Twist: each slice
//! u0 = const turned about e0 by rate u0. Identity: x = X.
struct DeformationMap {
  enum class Kind { Identity, Bend, Twist };
  Kind kind = Kind::Identity;
  std::array<double, 3> center{0, 0, 0};
  std::array<std::array<double, 3>, 3> axes{{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};
  double rate = 0;  //!< curvature (bend) or twist angle per unit length (twist)

  //! x = phi(X) and F = grad phi(X) (row-major).
  void apply(const double* X, double* x, double* F) const {
    double u[3];
    for (int a = 0; a < 3; ++a) {
      u[a] = 0;
      for (int d = 0; d < 3; ++d) u[a] += axes[a][d] * (X[d] - center[d]);
    }
    double v[3] = {u[0], u[1], u[2]};
    double G[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    if (kind == Kind::Bend && rate != 0) {
      const double t = rate * u[0], c = std::cos(t), s = std::sin(t), rho = 1 / rate;
      v[0] = (rho - u[2]) * s;
      v[2] = rho - (rho - u[2]) * c;
      const double g = 1 - rate * u[2];
      G[0] = g * c, G[2] = -s, G[6] = g * s, G[8] = c;
    } else if (kind == Kind::Twist) {
      const double t = rate * u[0], c = std::cos(t), s = std::sin(t);
      v[1] = c * u[1] - s * u[2];
      v[2] = s * u[1] + c * u[2];
      G[3] = rate * (-s * u[1] - c * u[2]), G[4] = c, G[5] = -s;
      G[6] = rate * (c * u[1] - s * u[2]), G[7] = s, G[8] = c;
    }
    // Back to world: x = c + E v, F = E G E^T (E's columns the axes).
    for (int d = 0; d < 3; ++d) {
      x[d] = center[d];
      for (int a = 0; a < 3; ++a) x[d] += axes[a][d] * v[a];
    }
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        double f = 0;
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b) f += axes[a][i] * G[3 * a + b] * axes[b][j];
        F[3 * i + j] = f;
      }
  }
};

//! The map `kind` fitted to `object`: centre and extents from the central box of its means
//! (2nd to 98th percentile per axis), e0 the world axis of the longest extent, e1 the next;
//! `degrees` is the total bend or twist angle over the extent along e0.
inline DeformationMap fit_map(const gaussians::SplatSet& object, DeformationMap::Kind kind,
                              double degrees) {
  const auto box = gaussians::central_box(gaussians::rest_frame(object));
  DeformationMap m;
  m.kind = kind;
  int order[3] = {0, 1, 2};
  double ext[3];
  for (int d = 0; d < 3; ++d) {
    m.center[d] = 0.5 * (box[0][d] + box[1][d]);
    ext[d] = box[1][d] - box[0][d];
  }
  for (int i = 0; i < 3; ++i)
    for (int j = i + 1; j < 3; ++j)
      if (ext[order[j]] > ext[order[i]]) std::swap(order[i], order[j]);
  m.axes = {};
  m.axes[0][order[0]] = 1;
  m.axes[1][order[1]] = 1;
  const auto& a = m.axes[0];
  const auto& b = m.axes[1];
  m.axes[2] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
  m.rate = degrees * M_PI / 180 / ext[order[0]];
  return m;
}

//! Ein(t) = int_0^t (1 - exp(-s)) / s ds (series; t <= 40).
inline double ein(double t) {
  double term = t, sum = t;
  for (int n = 2; n < 200; ++n) {
    term *= -t * (n - 1) / (double(n) * n);
    sum += term;
    if (std::abs(term) < 1e-17 * std::abs(sum)) break;
  }
  return sum;
}

//! How the ground truth subdivides each Gaussian (header comment): `components` groups n = 1..N
//! of `count` small Gaussians each, of covariance alpha^2 S, centred at samples of covariance
//! (1 / n - alpha^2) S.
struct Subdivision {
  double alpha = 0.6;  //!< small standard deviations / parent's; alpha^2 < 1 / components
  int count = 16;      //!< small Gaussians per group: even, >= 6
  int components = 2;  //!< groups N (the terms of the optical depth's series kept)
  std::uint64_t seed = 20240601;

  //! Opacity of each small Gaussian of group n (1..N) of a parent of opacity o (header
  //! comment), at most 0.99.
  double small_opacity(double o, int n) const {
    double c = std::pow(o, n) / n;
    if (n == components) {
      c = -std::log1p(-o);
      for (int m = 1; m < n; ++m) c -= std::pow(o, m) / m;
    }
    return std::min(0.99, ein(c / (count * alpha * alpha * n)));
  }
  //! std::invalid_argument unless components >= 1, 0 < alpha^2 < 1 / components and count is
  //! even and >= 6.
  void check() const {
    if (components < 1 || !(alpha > 0 && alpha * alpha * components < 1) || count < 6 ||
        count % 2 != 0)
      throw std::invalid_argument(
          "subdivision: alpha must lie in (0, 1 / sqrt(components)), count be even and >= 6");
  }
};

using driver::block;
using driver::rank_block;

//! The small Gaussians of parents [lo, hi) of `s` (header comment). Parent i's draws come from
//! a generator seeded by (seed, i), so the union over any split is the same.
inline gaussians::SplatSet subdivide(const gaussians::SplatSet& s, std::size_t lo, std::size_t hi,
                                     const Subdivision& sub) {
  sub.check();
  gaussians::SplatSet out;
  out.sh_degree = s.sh_degree;
  const int K = sub.count;
  const std::size_t nk = 3 * static_cast<std::size_t>(s.coefficients());
  std::vector<Eigen::Vector3d> w(K);
  for (std::size_t i = lo; i < hi; ++i) {
    std::mt19937_64 rng(sub.seed ^ (0x9E3779B97F4A7C15ull * (i + 1)));
    std::normal_distribution<double> g(0, 1);
    const Eigen::Quaterniond q(s.rotation[4 * i], s.rotation[4 * i + 1], s.rotation[4 * i + 2],
                               s.rotation[4 * i + 3]);
    const Eigen::Vector3d sc(s.scale[3 * i], s.scale[3 * i + 1], s.scale[3 * i + 2]);
    const Eigen::Matrix3d M = q.toRotationMatrix() * sc.asDiagonal();
    const Eigen::Vector3d mu(s.position[3 * i], s.position[3 * i + 1], s.position[3 * i + 2]);
    for (int n = 1; n <= sub.components; ++n) {
      // K / 2 normal draws and their negatives, whitened to mean 0 and covariance I.
      Eigen::LLT<Eigen::Matrix3d> llt;
      for (;;) {
        Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
        for (int k = 0; k < K / 2; ++k) {
          w[k] = Eigen::Vector3d(g(rng), g(rng), g(rng));
          w[k + K / 2] = -w[k];
          C += w[k] * w[k].transpose();
        }
        llt.compute(C * (2.0 / K));
        if (llt.info() == Eigen::Success &&
            llt.matrixL().toDenseMatrix().diagonal().minCoeff() > 1e-3)
          break;
      }
      const double spread = std::sqrt(1.0 / n - sub.alpha * sub.alpha);
      const double o = sub.small_opacity(s.opacity[i], n);
      for (int k = 0; k < K; ++k) {
        const Eigen::Vector3d x = mu + spread * (M * llt.matrixL().solve(w[k]));
        out.position.insert(out.position.end(), {x[0], x[1], x[2]});
        for (int d = 0; d < 3; ++d) out.scale.push_back(sub.alpha * sc[d]);
        out.rotation.insert(out.rotation.end(), &s.rotation[4 * i], &s.rotation[4 * i] + 4);
        out.opacity.push_back(o);
        out.sh.insert(out.sh.end(), &s.sh[nk * i], &s.sh[nk * i] + nk);
      }
    }
  }
  return out;
}

//! Every splat of `s` moved by `map`, covariance and harmonics per `opt`.
inline gaussians::SplatFrame deform(const gaussians::SplatSet& s, const DeformationMap& map,
                                    const gaussians::KinematicsOptions& opt) {
  gaussians::SplatFrame f;
  f.sh_degree = s.sh_degree;
  double x[3], F[9];
  for (std::size_t i = 0; i < s.size(); ++i) {
    map.apply(&s.position[3 * i], x, F);
    gaussians::append_deformed(s, i, x, F, opt, f);
  }
  return f;
}

//! `n` orbit cameras of `width` x `height` around the box framing both the rest and the
//! deformed (full method) object: azimuths 360 / n apart, elevations alternating 30 and -20
//! degrees.
inline std::vector<gaussians::Camera> orbit_cameras(const gaussians::SplatSet& object,
                                                    const DeformationMap& map, int n, int width,
                                                    int height) {
  gaussians::KinematicsOptions plain;
  plain.rotate_harmonics = false;
  gaussians::SplatFrame both = gaussians::rest_frame(object);
  both.append(deform(object, map, plain));
  gaussians::OrbitCamera orbit = gaussians::framing_orbit(both, width, height, 40);
  std::vector<gaussians::Camera> cams;
  for (int i = 0; i < n; ++i) {
    orbit.azimuth = 20 + 360.0 * i / n;
    orbit.elevation = i % 2 == 0 ? 30 : -20;
    cams.push_back(orbit.at_frame(0));
  }
  return cams;
}

//! Mean PSNR over the cameras of the four methods against the subdivided truth, and of the
//! subdivided object at rest against the original at rest.
struct Scores {
  double rest = 0;
  double method[4] = {0, 0, 0, 0};
  std::size_t parents = 0, small = 0;
};

//! Optional images of the first camera (rank 0): truth, each method, rest truth and original.
struct Images {
  gaussians::Image truth, rest_truth, rest;
  gaussians::Image method[4];
};

//! Renders the original object (replicated on every rank; each rank takes a block of parents
//! and their small Gaussians) deformed by `map` with the four methods and as the subdivided
//! truth from every camera (render_distributed: the same images at any rank count), and scores
//! them. `first` (may be null) receives the first camera's images on rank 0.
inline Scores evaluate(MPI_Comm comm, const gaussians::SplatSet& object, const DeformationMap& map,
                       const std::vector<gaussians::Camera>& cameras, const Subdivision& sub,
                       Images* first = nullptr) {
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  const auto [lo, hi] = rank_block(comm, object.size());
  const gaussians::SplatSet mine = block(object, lo, hi);
  const gaussians::SplatSet small = subdivide(object, lo, hi, sub);
  const gaussians::SplatFrame rest = gaussians::rest_frame(mine);
  const gaussians::SplatFrame rest_truth = gaussians::rest_frame(small);
  const gaussians::SplatFrame truth = deform(small, map, {});
  gaussians::SplatFrame method[4];
  for (int m = 0; m < 4; ++m)
    method[m] = deform(mine, map, gaussians::KinematicsOptions::parse(kMethods[m], "method"));

  Scores s;
  unsigned long counts[2] = {mine.size(), small.size()}, total[2];
  MPI_Allreduce(counts, total, 2, MPI_UNSIGNED_LONG, MPI_SUM, comm);
  s.parents = total[0];
  s.small = total[1];
  auto score = [&](const gaussians::Image& a, const gaussians::Image& b) {
    double v = rank == 0 ? gaussians::psnr(a, b) : 0;
    MPI_Bcast(&v, 1, MPI_DOUBLE, 0, comm);
    return v;
  };
  for (std::size_t c = 0; c < cameras.size(); ++c) {
    const auto& cam = cameras[c];
    const gaussians::Image rt = gaussians::render_distributed(comm, rest_truth, cam);
    const gaussians::Image r = gaussians::render_distributed(comm, rest, cam);
    s.rest += score(rt, r) / cameras.size();
    const gaussians::Image t = gaussians::render_distributed(comm, truth, cam);
    gaussians::Image im[4];
    for (int m = 0; m < 4; ++m) {
      im[m] = gaussians::render_distributed(comm, method[m], cam);
      s.method[m] += score(im[m], t) / cameras.size();
    }
    if (c == 0 && first != nullptr && rank == 0) {
      first->truth = t;
      first->rest_truth = rt;
      first->rest = r;
      for (int m = 0; m < 4; ++m) first->method[m] = im[m];
    }
  }
  return s;
}

}  // namespace gen4d::ablation
