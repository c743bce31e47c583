// fixed_corotated (PhysGaussian App. B.1, Stomakhin et al. 2012): purely elastic,
//   psi = mu |F - R|^2 + lambda/2 (J - 1)^2,   tau = 2 mu (F - R) F^T + lambda (J - 1) J I,
// evaluated in the signed SVD F = U Sigma V^T, R = U V^T, where (F - R) F^T = U (Sigma - I) Sigma
// U^T:
//   tau = U diag(2 mu (sigma_i - 1) sigma_i + lambda (J - 1) J) U^T   (exactly symmetric).
#include <memory>

#include "mpm/materials/Models.hpp"

namespace gen4d::mpm {

namespace {

using detail::Mat3;
using detail::Vec3;

inline Mat3 fixed_corotated_tau(const Mat3& U, const Vec3& s, double mu, double lambda) {
  const double J = s[0] * s[1] * s[2];
  const double vol = lambda * (J - 1) * J;
  const Vec3 t{{2 * mu * (s[0] - 1) * s[0] + vol, 2 * mu * (s[1] - 1) * s[1] + vol,
                2 * mu * (s[2] - 1) * s[2] + vol}};
  return detail::from_principal(U, t);
}

class FixedCorotated final : public ElasticBase {
 public:
  explicit FixedCorotated(const MaterialParams& p) : ElasticBase(p) {}
  std::string name() const override { return "fixed_corotated"; }
  std::vector<std::string> state_names() const override { return {}; }
  void update(std::size_t n, double* F, double*, double* tau, double) const override {
    stress(n, F, nullptr, tau);
  }
  void stress(std::size_t n, const double* F, const double*, double* tau) const override {
    detail::for_each_svd(n, F, [&](std::size_t i, const Mat3& U, const Vec3& s, const Mat3&) {
      detail::store3x3(fixed_corotated_tau(U, s, mu_, lambda_), tau + 9 * i);
    });
  }
};

}  // namespace

void register_fixed_corotated() {
  detail::add_material_entry({"fixed_corotated", {}, [](const MaterialParams& p) {
                                return std::make_unique<FixedCorotated>(p);
                              }});
}

}  // namespace gen4d::mpm
