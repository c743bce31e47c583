#include "gaussians/Splats.hpp"

#include <algorithm>

#include <cmath>
#include <stdexcept>

namespace gen4d::gaussians {

namespace {

void expect_length(const char* name, std::size_t got, std::size_t want) {
  if (got != want)
    throw std::logic_error(std::string("SplatSet: ") + name + " has " + std::to_string(got) +
                           " values, expected " + std::to_string(want));
}

}  // namespace

void SplatSet::check_sizes() const {
  if (sh_degree < 0 || sh_degree > kMaxShDegree)
    throw std::logic_error("SplatSet: sh_degree " + std::to_string(sh_degree) + " is outside 0.." +
                           std::to_string(kMaxShDegree));
  const std::size_t n = size();
  expect_length("position", position.size(), 3 * n);
  expect_length("scale", scale.size(), 3 * n);
  expect_length("rotation", rotation.size(), 4 * n);
  expect_length("sh", sh.size(), 3 * static_cast<std::size_t>(coefficients()) * n);
}

std::array<double, 6> SplatSet::covariance(std::size_t i) const {
  const double* q = &rotation[4 * i];
  const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  const double w = q[0] / norm, x = q[1] / norm, y = q[2] / norm, z = q[3] / norm;
  // Rotation of the unit quaternion (local -> world), row-major.
  const double R[9] = {1 - 2 * (y * y + z * z), 2 * (x * y - w * z),     2 * (x * z + w * y),
                       2 * (x * y + w * z),     1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                       2 * (x * z - w * y),     2 * (y * z + w * x),     1 - 2 * (x * x + y * y)};
  // M = R S; covariance M M^T.
  double M[9];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) M[3 * r + c] = R[3 * r + c] * scale[3 * i + c];
  auto dot = [&](int a, int b) {
    return M[3 * a] * M[3 * b] + M[3 * a + 1] * M[3 * b + 1] + M[3 * a + 2] * M[3 * b + 2];
  };
  return {dot(0, 0), dot(0, 1), dot(0, 2), dot(1, 1), dot(1, 2), dot(2, 2)};
}

void SplatFrame::append(const SplatFrame& other) {
  if (size() == 0 && sh.empty() && sh_rotation.empty()) sh_degree = other.sh_degree;
  if (other.sh_degree != sh_degree)
    throw std::logic_error("SplatFrame::append: SH degree " + std::to_string(other.sh_degree) +
                           " onto SH degree " + std::to_string(sh_degree));
  if (size() > 0 && other.size() > 0 && sh_rotation.empty() != other.sh_rotation.empty())
    throw std::logic_error("SplatFrame::append: frames with and without sh_rotation");
  position.insert(position.end(), other.position.begin(), other.position.end());
  covariance.insert(covariance.end(), other.covariance.begin(), other.covariance.end());
  opacity.insert(opacity.end(), other.opacity.begin(), other.opacity.end());
  sh.insert(sh.end(), other.sh.begin(), other.sh.end());
  sh_rotation.insert(sh_rotation.end(), other.sh_rotation.begin(), other.sh_rotation.end());
}

namespace {

//! SH coefficients of splat i at degree `to` (>= the set's), 3 per coefficient, appended.
void append_sh(const SplatSet& s, std::size_t i, int to, std::vector<double>& out) {
  const std::size_t have = 3 * static_cast<std::size_t>(s.coefficients());
  const std::size_t want = 3 * static_cast<std::size_t>(sh_coefficients(to));
  const double* src = s.sh.data() + i * have;
  out.insert(out.end(), src, src + have);
  out.insert(out.end(), want - have, 0.0);
}

}  // namespace

void append_splats(SplatSet& to, const SplatSet& from) {
  from.check_sizes();
  if (to.size() == 0) {
    to.sh_degree = std::max(to.sh_degree, from.sh_degree);
    to.sh.clear();
  }
  const int degree = std::max(to.sh_degree, from.sh_degree);
  if (degree != to.sh_degree) {
    std::vector<double> sh;
    for (std::size_t i = 0; i < to.size(); ++i) append_sh(to, i, degree, sh);
    to.sh = std::move(sh);
    to.sh_degree = degree;
  }
  to.position.insert(to.position.end(), from.position.begin(), from.position.end());
  to.scale.insert(to.scale.end(), from.scale.begin(), from.scale.end());
  to.rotation.insert(to.rotation.end(), from.rotation.begin(), from.rotation.end());
  to.opacity.insert(to.opacity.end(), from.opacity.begin(), from.opacity.end());
  for (std::size_t i = 0; i < from.size(); ++i) append_sh(from, i, degree, to.sh);
}

}  // namespace gen4d::gaussians
