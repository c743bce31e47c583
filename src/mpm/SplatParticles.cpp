#include "mpm/SplatParticles.hpp"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

#include "core/Error.hpp"
#include "gaussians/DeckSplats.hpp"
#include "parallel/Comm.hpp"
#include "parallel/Distribute.hpp"

namespace gen4d::mpm {

namespace {

constexpr double kShC0 = 0.28209479177387814;
using RowMat3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;

//! R S S^T R^T of standard deviations s and unit quaternion q (w, x, y, z), upper triangle.
void covariance_of(const double* s, const double* q, double* cov) {
  const Eigen::Quaterniond quat(q[0], q[1], q[2], q[3]);
  const Eigen::Matrix3d R = quat.normalized().toRotationMatrix();
  const Eigen::Matrix3d M = R * Eigen::Vector3d(s[0], s[1], s[2]).asDiagonal();
  const Eigen::Matrix3d A = M * M.transpose();
  cov[0] = A(0, 0), cov[1] = A(0, 1), cov[2] = A(0, 2);
  cov[3] = A(1, 1), cov[4] = A(1, 2), cov[5] = A(2, 2);
}

//! The covariance append_deformed draws for extra values `e` with total deformation F.
std::array<double, 6> deformed_covariance(const double* e, const std::array<double, 9>& F,
                                          const gaussians::KinematicsOptions& options,
                                          CovarianceUpdate mode) {
  std::array<double, 6> A0;
  covariance_of(e + SplatLayout::kScale, e + SplatLayout::kRotation, A0.data());
  switch (options.covariance) {
    case gaussians::KinematicsOptions::Covariance::Fixed:
      return A0;
    case gaussians::KinematicsOptions::Covariance::Rigid:
      return gaussians::transform_covariance(gaussians::polar_rotation(F), A0);
    case gaussians::KinematicsOptions::Covariance::Deformed:
      break;
  }
  if (mode == CovarianceUpdate::Rate) {
    std::array<double, 6> a;
    std::copy_n(e + SplatLayout::kCovariance, 6, a.begin());
    return a;
  }
  return gaussians::transform_covariance(F, A0);
}

}  // namespace

std::vector<std::string> SplatLayout::names() const {
  std::vector<std::string> n;
  for (const char* a : {"x", "y", "z"}) n.push_back(fmt::format("splat_scale_{}", a));
  for (const char* a : {"w", "x", "y", "z"}) n.push_back(fmt::format("splat_rotation_{}", a));
  for (int k = 0; k < 9; ++k) n.push_back(fmt::format("splat_F_{}{}", k / 3, k % 3));
  for (const char* a : {"xx", "xy", "xz", "yy", "yz", "zz"})
    n.push_back(fmt::format("splat_covariance_{}", a));
  n.push_back("splat_opacity");
  const int K = gaussians::sh_coefficients(sh_degree);
  for (int k = 0; k < K; ++k)
    for (int c = 0; c < 3; ++c) n.push_back(fmt::format("splat_sh_{}_{}", k, "rgb"[c]));
  return n;
}

SplatLayout SplatLayout::from_names(const std::vector<std::string>& names,
                                    const std::string& where) {
  for (int degree = 0; degree <= gaussians::kMaxShDegree; ++degree) {
    SplatLayout layout{degree};
    if (layout.names() == names) return layout;
  }
  throw InputError(where + fmt::format(": the {} extra particle values are not the splat "
                                       "attributes of any SH degree 0..{}",
                                       names.size(), gaussians::kMaxShDegree));
}

CovarianceUpdate parse_covariance_update(const std::string& name, const std::string& where) {
  if (name == "deformation_gradient") return CovarianceUpdate::DeformationGradient;
  if (name == "rate") return CovarianceUpdate::Rate;
  throw InputError(where + ": '" + name + "' is not \"deformation_gradient\" or \"rate\"");
}

void splat_rest_values(const gaussians::SplatSet& s, std::size_t i, const SplatLayout& layout,
                       double* out) {
  if (s.sh_degree > layout.sh_degree)
    throw std::logic_error(fmt::format("splat_rest_values: SH degree {} into a layout of degree {}",
                                       s.sh_degree, layout.sh_degree));
  std::fill_n(out, layout.width(), 0.0);
  std::copy_n(&s.scale[3 * i], 3, out + SplatLayout::kScale);
  std::copy_n(&s.rotation[4 * i], 4, out + SplatLayout::kRotation);
  for (int d = 0; d < 3; ++d) out[SplatLayout::kF + 4 * d] = 1.0;
  covariance_of(out + SplatLayout::kScale, out + SplatLayout::kRotation,
                out + SplatLayout::kCovariance);
  out[SplatLayout::kOpacity] = s.opacity[i];
  const std::size_t per = 3 * static_cast<std::size_t>(s.coefficients());
  std::copy_n(&s.sh[per * i], per, out + SplatLayout::kSh);
}

void isotropic_rest_values(double sigma, double opacity, const double* rgb,
                           const SplatLayout& layout, double* out) {
  std::fill_n(out, layout.width(), 0.0);
  for (int d = 0; d < 3; ++d) out[SplatLayout::kScale + d] = sigma;
  out[SplatLayout::kRotation] = 1.0;
  for (int d = 0; d < 3; ++d) out[SplatLayout::kF + 4 * d] = 1.0;
  const double var = sigma * sigma;
  out[SplatLayout::kCovariance + 0] = var;
  out[SplatLayout::kCovariance + 3] = var;
  out[SplatLayout::kCovariance + 5] = var;
  out[SplatLayout::kOpacity] = opacity;
  for (int c = 0; c < 3; ++c) out[SplatLayout::kSh + c] = (rgb[c] - 0.5) / kShC0;
}

void advance_splats(Particles& p, const SplatLayout& layout, double dt, CovarianceUpdate mode) {
  const int W = layout.width();
  if (p.extra_width != W)
    throw std::logic_error(
        fmt::format("advance_splats: particles carry {} extra values, the "
                    "splat layout {}",
                    p.extra_width, W));
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (p.flag[i] & 1) continue;
    const double* Cm = &p.C[9 * i];
    double* e = &p.extra[static_cast<std::size_t>(W) * i];
    advance_deformation(Cm, dt, e + SplatLayout::kF);  // as the solver advances its F
    if (mode == CovarianceUpdate::Rate) {
      std::array<double, 9> L;
      std::copy_n(Cm, 9, L.begin());
      std::array<double, 6> a;
      std::copy_n(e + SplatLayout::kCovariance, 6, a.begin());
      gaussians::rate_update_covariance(L, dt, a);
      std::copy(a.begin(), a.end(), e + SplatLayout::kCovariance);
    }
  }
}

gaussians::SplatSet rest_splats(const Particles& p, const SplatLayout& layout) {
  const int W = layout.width();
  const std::size_t n = p.size(), per = static_cast<std::size_t>(W - SplatLayout::kSh);
  gaussians::SplatSet s;
  s.sh_degree = layout.sh_degree;
  s.position = p.x;
  s.scale.resize(3 * n);
  s.rotation.resize(4 * n);
  s.opacity.resize(n);
  s.sh.resize(per * n);
  for (std::size_t i = 0; i < n; ++i) {
    const double* e = &p.extra[static_cast<std::size_t>(W) * i];
    std::copy_n(e + SplatLayout::kScale, 3, &s.scale[3 * i]);
    std::copy_n(e + SplatLayout::kRotation, 4, &s.rotation[4 * i]);
    s.opacity[i] = e[SplatLayout::kOpacity];
    std::copy_n(e + SplatLayout::kSh, per, &s.sh[per * i]);
  }
  return s;
}

gaussians::SplatFrame splat_frame(const Particles& p, const SplatLayout& layout,
                                  const gaussians::KinematicsOptions& options,
                                  CovarianceUpdate mode) {
  const gaussians::SplatSet rest = rest_splats(p, layout);
  const std::size_t W = static_cast<std::size_t>(layout.width());
  gaussians::SplatFrame frame;
  frame.sh_degree = layout.sh_degree;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const double* e = &p.extra[W * i];
    gaussians::append_deformed(
        rest, i, &p.x[3 * i], e + SplatLayout::kF, options, frame,
        mode == CovarianceUpdate::Rate ? e + SplatLayout::kCovariance : nullptr);
  }
  return frame;
}

gaussians::SplatSet gather_deformed_splats(MPI_Comm comm, const Particles& p,
                                           const SplatLayout& layout,
                                           const gaussians::KinematicsOptions& options,
                                           CovarianceUpdate mode) {
  const int rank = parallel::rank(comm);
  std::vector<std::int64_t> id = p.id;
  std::vector<double> x = p.x, extra = p.extra;
  const int W = layout.width();
  parallel::RowExchange ex;
  ex.add(id, 1).add(x, 3).add(extra, W);
  ex.exchange(comm, std::vector<int>(id.size(), 0));
  gaussians::SplatSet out;
  out.sh_degree = layout.sh_degree;
  if (rank != 0) return out;
  std::vector<std::size_t> order(id.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](auto a, auto b) { return id[a] < id[b]; });
  Particles sorted;
  sorted.extra_width = W;
  for (std::size_t i : order) {
    sorted.x.insert(sorted.x.end(), &x[3 * i], &x[3 * i] + 3);
    sorted.extra.insert(sorted.extra.end(), &extra[static_cast<std::size_t>(W) * i],
                        &extra[static_cast<std::size_t>(W) * (i + 1)]);
  }
  sorted.id.resize(order.size());
  out = rest_splats(sorted, layout);
  const std::size_t n = order.size(), per = static_cast<std::size_t>(W - SplatLayout::kSh);
  for (std::size_t i = 0; i < n; ++i) {
    const double* e = &sorted.extra[static_cast<std::size_t>(W) * i];
    std::array<double, 9> Fm;
    std::copy_n(e + SplatLayout::kF, 9, Fm.begin());
    const std::array<double, 6> c = deformed_covariance(e, Fm, options, mode);
    Eigen::Matrix3d A;
    A << c[0], c[1], c[2], c[1], c[3], c[4], c[2], c[4], c[5];
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(A);
    Eigen::Matrix3d V = eig.eigenvectors();
    if (V.determinant() < 0) V.col(2) = -V.col(2);
    const Eigen::Quaterniond q(V);
    const double quat[4] = {q.w(), q.x(), q.y(), q.z()};
    std::copy_n(quat, 4, &out.rotation[4 * i]);
    for (int d = 0; d < 3; ++d)
      out.scale[3 * i + d] = std::sqrt(std::max(eig.eigenvalues()[d], 1e-30));
    if (options.rotate_harmonics && layout.sh_degree > 0) {
      const std::array<double, 9> R = gaussians::polar_rotation(Fm);
      gaussians::SplatSet single;
      single.sh_degree = layout.sh_degree;
      single.position = {0, 0, 0};
      single.scale = {1, 1, 1};
      single.rotation = {1, 0, 0, 0};
      single.opacity = {out.opacity[i]};
      single.sh.assign(&out.sh[per * i], &out.sh[per * i] + per);
      gaussians::transform_splats(single, 1.0, R, {0, 0, 0});
      std::copy(single.sh.begin(), single.sh.end(), &out.sh[per * i]);
    }
  }
  return out;
}

}  // namespace gen4d::mpm
