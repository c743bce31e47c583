// stvk_hencky (PhysGaussian App. B.2, Klar et al. 2016): purely elastic StVK energy in the
// logarithmic (Hencky) strain of the signed SVD F = U Sigma V^T,
//   eps = log(Sigma) (sigma_i clamped at kMinStretch),  psi = mu |eps|^2 + lambda/2 tr(eps)^2,
//   tau = U (2 mu eps + lambda tr(eps) I) U^T.
#include <memory>

#include "mpm/materials/Models.hpp"

namespace gen4d::mpm {

namespace {

using detail::Mat3;
using detail::Vec3;

inline Mat3 stvk_hencky_tau(const Mat3& U, const Vec3& s, double mu, double lambda) {
  return detail::from_principal(U,
                                detail::hencky_principal_tau(detail::hencky_strain(s), mu, lambda));
}

class StvkHencky final : public ElasticBase {
 public:
  explicit StvkHencky(const MaterialParams& p) : ElasticBase(p) {}
  std::string name() const override { return "stvk_hencky"; }
  std::vector<std::string> state_names() const override { return {}; }
  void update(std::size_t n, double* F, double*, double* tau, double) const override {
    stress(n, F, nullptr, tau);
  }
  void stress(std::size_t n, const double* F, const double*, double* tau) const override {
    detail::for_each_svd(n, F, [&](std::size_t i, const Mat3& U, const Vec3& s, const Mat3&) {
      detail::store3x3(stvk_hencky_tau(U, s, mu_, lambda_), tau + 9 * i);
    });
  }
};

}  // namespace

void register_stvk_hencky() {
  detail::add_material_entry(
      {"stvk_hencky", {}, [](const MaterialParams& p) { return std::make_unique<StvkHencky>(p); }});
}

}  // namespace gen4d::mpm
