#include "gaussians/Kinematics.hpp"

#include <Eigen/Dense>

#include <cmath>
#include <stdexcept>

#include "core/Error.hpp"

namespace gen4d::gaussians {

namespace {

using Mat3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;

Mat3 full(const std::array<double, 6>& a) {
  Mat3 m;
  m << a[0], a[1], a[2], a[1], a[3], a[4], a[2], a[4], a[5];
  return m;
}

std::array<double, 6> upper(const Mat3& m) {
  return {m(0, 0), m(0, 1), m(0, 2), m(1, 1), m(1, 2), m(2, 2)};
}

}  // namespace

KinematicsOptions KinematicsOptions::parse(const std::string& name, const std::string& where) {
  KinematicsOptions opt;
  if (name == "full") return opt;
  if (name == "fixed_covariance") {
    opt.covariance = Covariance::Fixed;
  } else if (name == "rigid_covariance") {
    opt.covariance = Covariance::Rigid;
  } else if (name == "fixed_harmonics") {
    opt.rotate_harmonics = false;
  } else {
    throw InputError(where + ": unknown kinematics '" + name +
                     "' (expected full, fixed_covariance, rigid_covariance or fixed_harmonics)");
  }
  return opt;
}

std::array<double, 9> polar_rotation(const std::array<double, 9>& F) {
  for (double v : F)
    if (!std::isfinite(v))
      throw RuntimeError("polar_rotation: the deformation gradient has a non-finite entry");
  const Mat3 f = Eigen::Map<const Mat3>(F.data());
  const Eigen::JacobiSVD<Mat3> svd(f, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat3 U = svd.matrixU();
  const Mat3& V = svd.matrixV();
  // Singular values are sorted decreasingly: flipping the last column of U turns an improper
  // U V^T into the rotation nearest to F among those with det +1.
  if (U.determinant() * V.determinant() < 0) U.col(2) = -U.col(2);
  const Mat3 R = U * V.transpose();
  std::array<double, 9> out;
  Eigen::Map<Mat3>(out.data()) = R;
  return out;
}

std::array<double, 6> transform_covariance(const std::array<double, 9>& F,
                                           const std::array<double, 6>& A) {
  const Mat3 f = Eigen::Map<const Mat3>(F.data());
  return upper(f * full(A) * f.transpose());
}

void rate_update_covariance(const std::array<double, 9>& L, double dt, std::array<double, 6>& a) {
  const Mat3 l = Eigen::Map<const Mat3>(L.data());
  const Mat3 m = full(a);
  const Mat3 la = l * m;
  const Mat3 next = m + dt * (la + la.transpose());
  a = upper(next);
}

void append_deformed(const SplatSet& rest, std::size_t i, const double* x, const double* F,
                     const KinematicsOptions& opt, SplatFrame& out,
                     const double* covariance_override) {
  if (out.sh_degree != rest.sh_degree)
    throw std::logic_error("append_deformed: frame of SH degree " + std::to_string(out.sh_degree) +
                           " for splats of SH degree " + std::to_string(rest.sh_degree));
  if (out.sh_rotation.size() != (opt.rotate_harmonics ? 9 * out.size() : 0))
    throw std::logic_error("append_deformed: the frame's sh_rotation does not match the options");
  std::array<double, 9> f;
  std::copy(F, F + 9, f.begin());
  const bool need_rotation =
      opt.rotate_harmonics || opt.covariance == KinematicsOptions::Covariance::Rigid;
  std::array<double, 9> R{};
  if (need_rotation) R = polar_rotation(f);

  std::array<double, 6> cov;
  switch (opt.covariance) {
    case KinematicsOptions::Covariance::Deformed:
      if (covariance_override != nullptr)
        std::copy(covariance_override, covariance_override + 6, cov.begin());
      else
        cov = transform_covariance(f, rest.covariance(i));
      break;
    case KinematicsOptions::Covariance::Fixed:
      cov = rest.covariance(i);
      break;
    case KinematicsOptions::Covariance::Rigid:
      cov = transform_covariance(R, rest.covariance(i));
      break;
  }

  for (int d = 0; d < 3; ++d) out.position.push_back(static_cast<float>(x[d]));
  for (double c : cov) out.covariance.push_back(static_cast<float>(c));
  out.opacity.push_back(static_cast<float>(rest.opacity[i]));
  const std::size_t per = 3 * static_cast<std::size_t>(rest.coefficients());
  for (std::size_t k = 0; k < per; ++k) out.sh.push_back(static_cast<float>(rest.sh[i * per + k]));
  if (opt.rotate_harmonics)
    for (double r : R) out.sh_rotation.push_back(static_cast<float>(r));
}

SplatFrame rest_frame(const SplatSet& rest) {
  rest.check_sizes();
  SplatFrame frame;
  frame.sh_degree = rest.sh_degree;
  const std::size_t n = rest.size();
  frame.position.assign(rest.position.begin(), rest.position.end());
  frame.covariance.resize(6 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::array<double, 6> c = rest.covariance(i);
    for (int k = 0; k < 6; ++k) frame.covariance[6 * i + k] = static_cast<float>(c[k]);
  }
  frame.opacity.assign(rest.opacity.begin(), rest.opacity.end());
  frame.sh.assign(rest.sh.begin(), rest.sh.end());
  return frame;
}

}  // namespace gen4d::gaussians
