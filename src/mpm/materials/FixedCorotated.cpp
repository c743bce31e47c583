// fixed_corotated (PhysGaussian App. B.1, Stomakhin et al. 2012): purely elastic,
//   psi = mu |F - R|^2 + lambda/2 (J - 1)^2,   tau = 2 mu (F - R) F^T + lambda (J - 1) J I,
// evaluated in the signed SVD F = U Sigma V^T, R = U V^T, where (F - R) F^T = U (Sigma - I) Sigma
// U^T:
//   tau = U diag(2 mu (sigma_i - 1) sigma_i + lambda (J - 1) J) U^T   (exactly symmetric).
#include "mpm/materials/Models.hpp"

namespace gen4d::mpm {

namespace {

struct FixedCorotatedLaw {
  static constexpr const char* kName = "fixed_corotated";
  static void stress(std::size_t n, const double* F, double mu, double lambda, double* tau) {
    using detail::Mat3;
    using detail::Vec3;
    detail::for_each_svd(n, F, [&](std::size_t i, const Mat3& U, const Vec3& s, const Mat3&) {
      detail::store3x3(detail::from_principal(U, detail::corotated_principal_tau(s, mu, lambda)),
                       tau + 9 * i);
    });
  }
};

}  // namespace

void register_fixed_corotated() {
  detail::add_model<Hyperelastic<FixedCorotatedLaw>>(FixedCorotatedLaw::kName);
}

}  // namespace gen4d::mpm
