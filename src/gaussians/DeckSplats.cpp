#include "gaussians/DeckSplats.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "core/Error.hpp"
#include "core/Log.hpp"
#include "gaussians/Filling.hpp"
#include "gaussians/Ply.hpp"

namespace gen4d::gaussians {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kC0 = 0.28209479177387814;
constexpr std::int64_t kMaxCell = std::int64_t{1} << 30;

using Mat3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;

//! The 16 real SH basis functions of degree <= 3 at the unit direction d, with the signs and
//! constants the 3DGS rasterizer uses (gaussians/SphericalHarmonics.hpp).
std::array<double, 16> sh_basis(const Eigen::Vector3d& d) {
  const double c1 = 0.4886025119029199;
  const double c2[5] = {1.0925484305920792, -1.0925484305920792, 0.31539156525252005,
                        -1.0925484305920792, 0.5462742152960396};
  const double c3[7] = {-0.5900435899266435, 2.890611442640554,   -0.4570457994644658,
                        0.3731763325901154,  -0.4570457994644658, 1.445305721320277,
                        -0.5900435899266435};
  const double x = d.x(), y = d.y(), z = d.z();
  const double xx = x * x, yy = y * y, zz = z * z;
  return {kC0,
          -c1 * y,
          c1 * z,
          -c1 * x,
          c2[0] * x * y,
          c2[1] * y * z,
          c2[2] * (2 * zz - xx - yy),
          c2[3] * x * z,
          c2[4] * (xx - yy),
          c3[0] * y * (3 * xx - yy),
          c3[1] * x * y * z,
          c3[2] * y * (4 * zz - xx - yy),
          c3[3] * z * (2 * zz - 3 * xx - 3 * yy),
          c3[4] * x * (4 * zz - xx - yy),
          c3[5] * z * (xx - yy),
          c3[6] * x * (xx - 3 * yy)};
}

//! For each band l = 1..degree, the matrix D_l with sum_m (D_l c)_m Y_lm(d) =
//! sum_m c_m Y_lm(R^T d) for every direction d: fitted on generic directions, exact up to
//! rounding because rotations keep each band.
std::vector<Eigen::MatrixXd> sh_band_rotations(int degree, const Mat3& R) {
  constexpr int kSamples = 32;
  std::vector<std::array<double, 16>> at, at_rotated;
  for (int j = 0; j < kSamples; ++j) {
    // Fibonacci sphere directions.
    const double z = 1 - (2 * j + 1.0) / kSamples;
    const double r = std::sqrt(1 - z * z);
    const double phi = j * kPi * (3 - std::sqrt(5.0));
    const Eigen::Vector3d d(r * std::cos(phi), r * std::sin(phi), z);
    at.push_back(sh_basis(d));
    at_rotated.push_back(sh_basis(R.transpose() * d));
  }
  std::vector<Eigen::MatrixXd> bands;
  for (int l = 1; l <= degree; ++l) {
    const int first = l * l, width = 2 * l + 1;
    Eigen::MatrixXd B(kSamples, width), Br(kSamples, width);
    for (int j = 0; j < kSamples; ++j)
      for (int m = 0; m < width; ++m) {
        B(j, m) = at[j][first + m];
        Br(j, m) = at_rotated[j][first + m];
      }
    bands.push_back(B.colPivHouseholderQr().solve(Br));
  }
  return bands;
}

std::array<double, 4> quaternion_of(const Mat3& R) {
  // Shepperd's method: divide by the largest of 4 w^2, 4 x^2, 4 y^2, 4 z^2.
  const double t = R.trace();
  std::array<double, 4> q;
  if (t >= R(0, 0) && t >= R(1, 1) && t >= R(2, 2)) {
    const double s = 2 * std::sqrt(1 + t);
    q = {s / 4, (R(2, 1) - R(1, 2)) / s, (R(0, 2) - R(2, 0)) / s, (R(1, 0) - R(0, 1)) / s};
  } else if (R(0, 0) >= R(1, 1) && R(0, 0) >= R(2, 2)) {
    const double s = 2 * std::sqrt(1 + R(0, 0) - R(1, 1) - R(2, 2));
    q = {(R(2, 1) - R(1, 2)) / s, s / 4, (R(0, 1) + R(1, 0)) / s, (R(0, 2) + R(2, 0)) / s};
  } else if (R(1, 1) >= R(2, 2)) {
    const double s = 2 * std::sqrt(1 + R(1, 1) - R(0, 0) - R(2, 2));
    q = {(R(0, 2) - R(2, 0)) / s, (R(0, 1) + R(1, 0)) / s, s / 4, (R(1, 2) + R(2, 1)) / s};
  } else {
    const double s = 2 * std::sqrt(1 + R(2, 2) - R(0, 0) - R(1, 1));
    q = {(R(1, 0) - R(0, 1)) / s, (R(0, 2) + R(2, 0)) / s, (R(1, 2) + R(2, 1)) / s, s / 4};
  }
  return q;
}

std::uint64_t row_key(std::int64_t a, std::int64_t b) {
  return (static_cast<std::uint64_t>(a + kMaxCell) << 32) |
         static_cast<std::uint64_t>(b + kMaxCell);
}

}  // namespace

SplatSet load_geometry_splats(const GeometryConfig& g) {
  if (!(g.scale > 0) || !std::isfinite(g.scale))
    throw InputError(g.file + ": splat scale " + std::to_string(g.scale) + " is not positive");
  const Eigen::Vector3d axis(g.rotate_axis[0], g.rotate_axis[1], g.rotate_axis[2]);
  if (g.rotate_degrees != 0 && !(axis.norm() > 0))
    throw InputError(g.file + ": rotate_axis is zero");
  SplatSet all = read_splats_ply(g.file);
  const int K = all.coefficients();
  SplatSet kept;
  kept.sh_degree = all.sh_degree;
  for (std::size_t i = 0; i < all.size(); ++i) {
    if (all.opacity[i] < g.opacity_threshold) continue;
    kept.position.insert(kept.position.end(), &all.position[3 * i], &all.position[3 * i + 3]);
    kept.scale.insert(kept.scale.end(), &all.scale[3 * i], &all.scale[3 * i + 3]);
    kept.rotation.insert(kept.rotation.end(), &all.rotation[4 * i], &all.rotation[4 * i + 4]);
    kept.opacity.push_back(all.opacity[i]);
    kept.sh.insert(kept.sh.end(), &all.sh[3 * K * i], &all.sh[3 * K * (i + 1)]);
  }
  if (kept.size() == 0)
    throw InputError(g.file + ": none of its " + std::to_string(all.size()) +
                     " Gaussians has opacity >= " + std::to_string(g.opacity_threshold));
  Mat3 R = Mat3::Identity();
  if (g.rotate_degrees != 0)
    R = Eigen::AngleAxisd(g.rotate_degrees * kPi / 180, axis.normalized()).toRotationMatrix();
  std::array<double, 9> r;
  Eigen::Map<Mat3>(r.data()) = R;
  transform_splats(kept, g.scale, r, g.translate);
  if (g.fill_cells > 0) {
    FillingOptions fill;
    fill.n_grid = g.fill_cells;
    const FillingResult filled = fill_interior(kept, fill);
    log::info(
        "{}: {} particles filled in ({} interior and {} surface cells of {:.3g} m; {} "
        "Gaussians' supports clamped) in {:.2f} s",
        g.file, filled.particles.size(), filled.interior_cells, filled.surface_cells, filled.dx,
        filled.clamped_splats, filled.seconds_total);
    append_splats(kept, filled.particles);
  }
  return kept;
}

void transform_splats(SplatSet& splats, double scale, const std::array<double, 9>& R,
                      const std::array<double, 3>& t) {
  splats.check_sizes();
  if (!(scale > 0) || !std::isfinite(scale))
    throw std::invalid_argument("transform_splats: scale " + std::to_string(scale) +
                                " is not positive");
  const Mat3 r = Eigen::Map<const Mat3>(R.data());
  if (!r.allFinite() || (r * r.transpose() - Mat3::Identity()).norm() > 1e-9 ||
      r.determinant() <= 0)
    throw std::invalid_argument("transform_splats: R is not a rotation");
  const std::array<double, 4> qr = quaternion_of(r);
  const bool turns = r != Mat3::Identity();
  const int K = splats.coefficients();
  std::vector<Eigen::MatrixXd> bands;
  if (turns && splats.sh_degree > 0) bands = sh_band_rotations(splats.sh_degree, r);
  for (std::size_t i = 0; i < splats.size(); ++i) {
    double* p = &splats.position[3 * i];
    const Eigen::Vector3d moved = scale * (r * Eigen::Vector3d(p[0], p[1], p[2]));
    for (int d = 0; d < 3; ++d) p[d] = moved[d] + t[d];
    for (int d = 0; d < 3; ++d) splats.scale[3 * i + d] *= scale;
    if (!turns) continue;
    double* q = &splats.rotation[4 * i];
    const double w = qr[0] * q[0] - qr[1] * q[1] - qr[2] * q[2] - qr[3] * q[3];
    const double x = qr[0] * q[1] + qr[1] * q[0] + qr[2] * q[3] - qr[3] * q[2];
    const double y = qr[0] * q[2] - qr[1] * q[3] + qr[2] * q[0] + qr[3] * q[1];
    const double z = qr[0] * q[3] + qr[1] * q[2] - qr[2] * q[1] + qr[3] * q[0];
    q[0] = w, q[1] = x, q[2] = y, q[3] = z;
    double* sh = &splats.sh[3 * K * i];
    for (int l = 1; l <= splats.sh_degree; ++l) {
      const int first = l * l, width = 2 * l + 1;
      for (int c = 0; c < 3; ++c) {
        Eigen::VectorXd v(width);
        for (int m = 0; m < width; ++m) v[m] = sh[3 * (first + m) + c];
        const Eigen::VectorXd turned = bands[l - 1] * v;
        for (int m = 0; m < width; ++m) sh[3 * (first + m) + c] = turned[m];
      }
    }
  }
}

SplatSet splats_from_shape(const geometry::Shape& shape, double spacing,
                           std::array<double, 3> color, double opacity) {
  if (!(spacing > 0) || !std::isfinite(spacing))
    throw std::invalid_argument("splats_from_shape: spacing " + std::to_string(spacing) +
                                " is not positive");
  if (!(opacity > 0 && opacity < 1))
    throw std::invalid_argument("splats_from_shape: opacity " + std::to_string(opacity) +
                                " is outside (0, 1)");
  SplatSet s;
  const geometry::Aabb box = shape.bounds();
  if (box.empty()) return s;
  std::array<long, 3> n{};
  double total = 1;
  for (int d = 0; d < 3; ++d) {
    const double cells = std::ceil((box.hi[d] - box.lo[d]) / spacing - 1e-9);
    n[d] = std::max(1L, static_cast<long>(std::min(cells, 4e9)));
    total *= static_cast<double>(n[d]);
  }
  if (total > 2147483648.0)
    throw InputError("splats_from_shape: spacing " + std::to_string(spacing) +
                     " gives a lattice of " + std::to_string(total) +
                     " points over the shape's bounding box (more than 2^31)");
  const double sigma = spacing / 2;
  for (long k = 0; k < n[2]; ++k)
    for (long j = 0; j < n[1]; ++j)
      for (long i = 0; i < n[0]; ++i) {
        const Eigen::Vector3d p = box.lo + spacing * Eigen::Vector3d(i + 0.5, j + 0.5, k + 0.5);
        if (!shape.inside(p)) continue;
        s.position.insert(s.position.end(), {p.x(), p.y(), p.z()});
        s.scale.insert(s.scale.end(), {sigma, sigma, sigma});
        s.rotation.insert(s.rotation.end(), {1.0, 0.0, 0.0, 0.0});
        s.opacity.push_back(opacity);
        for (int c = 0; c < 3; ++c) s.sh.push_back((color[c] - 0.5) / kC0);
      }
  return s;
}

SplatOccupancy::SplatOccupancy(const SplatSet& splats, double h, std::array<double, 3> origin,
                               int min_count)
    : h_(h), origin_(origin[0], origin[1], origin[2]) {
  if (!(h > 0) || !std::isfinite(h))
    throw std::invalid_argument("SplatOccupancy: cell size " + std::to_string(h) +
                                " is not positive");
  if (min_count < 1)
    throw std::invalid_argument("SplatOccupancy: min_count " + std::to_string(min_count) +
                                " is below 1");
  splats.check_sizes();
  std::vector<std::array<std::int64_t, 3>> cells(splats.size());
  for (std::size_t s = 0; s < splats.size(); ++s)
    for (int d = 0; d < 3; ++d) {
      const double c = std::floor((splats.position[3 * s + d] - origin_[d]) / h_);
      if (!(std::abs(c) < static_cast<double>(kMaxCell)))
        throw InputError("SplatOccupancy: splat " + std::to_string(s) + " lies more than 2^30 " +
                         "cells of size " + std::to_string(h) + " from the origin");
      cells[s][d] = static_cast<std::int64_t>(c);
    }
  std::sort(cells.begin(), cells.end());
  std::array<std::int64_t, 3> lo{kMaxCell, kMaxCell, kMaxCell}, hi{-kMaxCell, -kMaxCell, -kMaxCell};
  for (std::size_t a = 0; a < cells.size();) {
    std::size_t b = a;
    while (b < cells.size() && cells[b] == cells[a]) ++b;
    if (static_cast<long>(b - a) >= min_count) {
      const auto& c = cells[a];
      ++occupied_;
      for (int d = 0; d < 3; ++d) {
        lo[d] = std::min(lo[d], c[d]);
        hi[d] = std::max(hi[d], c[d]);
      }
      // Axis a's row is keyed by the other two coordinates in increasing axis order.
      for (int axis = 0; axis < 3; ++axis) {
        const int u = axis == 0 ? 1 : 0, v = axis == 2 ? 1 : 2;
        const auto value = static_cast<std::int32_t>(c[axis]);
        auto [it, fresh] = rows_[axis].try_emplace(row_key(c[u], c[v]), value, value);
        if (!fresh) {
          it->second.first = std::min(it->second.first, value);
          it->second.second = std::max(it->second.second, value);
        }
      }
    }
    a = b;
  }
  if (occupied_ > 0)
    for (int d = 0; d < 3; ++d) {
      bounds_.lo[d] = origin_[d] + h_ * static_cast<double>(lo[d]);
      bounds_.hi[d] = origin_[d] + h_ * static_cast<double>(hi[d] + 1);
    }
}

bool SplatOccupancy::solid(long i, long j, long k) const {
  const long c[3] = {i, j, k};
  for (int axis = 0; axis < 3; ++axis) {
    const int u = axis == 0 ? 1 : 0, v = axis == 2 ? 1 : 2;
    if (std::abs(c[u]) >= kMaxCell || std::abs(c[v]) >= kMaxCell) return false;
    const auto it = rows_[axis].find(row_key(c[u], c[v]));
    // An unoccupied cell between the row's lowest and highest occupied cells has occupied cells
    // on both sides along this axis; an occupied cell is inside every row through it.
    if (it == rows_[axis].end() || c[axis] < it->second.first || c[axis] > it->second.second)
      return false;
  }
  return true;
}

bool SplatOccupancy::inside(const Eigen::Vector3d& p) const {
  long c[3];
  for (int d = 0; d < 3; ++d) {
    const double x = std::floor((p[d] - origin_[d]) / h_);
    if (!(std::abs(x) < static_cast<double>(kMaxCell))) return false;
    c[d] = static_cast<long>(x);
  }
  return solid(c[0], c[1], c[2]);
}

long SplatOccupancy::solid_cells() const {
  long count = 0;
  for (const auto& [key, range] : rows_[0]) {
    const long j = static_cast<long>(key >> 32) - kMaxCell;
    const long k = static_cast<long>(key & 0xffffffffu) - kMaxCell;
    for (long i = range.first; i <= range.second; ++i) count += solid(i, j, k);
  }
  return count;
}

}  // namespace gen4d::gaussians
