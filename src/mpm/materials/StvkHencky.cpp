// stvk_hencky (PhysGaussian App. B.2, Klar et al. 2016): purely elastic StVK energy in the
// logarithmic (Hencky) strain of the signed SVD F = U Sigma V^T,
//   eps = log(Sigma) (sigma_i clamped at kMinStretch),  psi = mu |eps|^2 + lambda/2 tr(eps)^2,
//   tau = U (2 mu eps + lambda tr(eps) I) U^T.
#include "mpm/materials/Models.hpp"

namespace gen4d::mpm {

namespace {

struct StvkHenckyLaw {
  static constexpr const char* kName = "stvk_hencky";
  static void stress(std::size_t n, const double* F, double mu, double lambda, double* tau) {
    detail::hencky_stress_batch(n, F, mu, lambda, tau);
  }
};

}  // namespace

void register_stvk_hencky() {
  detail::add_model<Hyperelastic<StvkHenckyLaw>>(StvkHenckyLaw::kName);
}

}  // namespace gen4d::mpm
