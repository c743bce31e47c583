// neo_hookean (PhysGaussian App. B.3; the seed lost the lambda in front of log J):
//   psi = mu/2 (tr(F^T F) - 3) - mu log J + lambda/2 (log J)^2,
//   tau = mu (F F^T - I) + lambda log(J) I,
// with J clamped at kMinStretch^3 so inverted particles get a large finite restoring pressure.
// (The voxel solvers' Neo-Hookean is the stable one, `stable_neo_hookean`.)
#include <algorithm>
#include <cmath>

#include "mpm/materials/Models.hpp"

namespace gen4d::mpm {

namespace {

struct NeoHookeanLaw {
  static constexpr const char* kName = "neo_hookean";
  static detail::Mat3 tau_of(const detail::Mat3& F, double mu, double lambda) {
    constexpr double kMinJ = detail::kMinStretch * detail::kMinStretch * detail::kMinStretch;
    const double logJ = std::log(std::max(materials::det(F), kMinJ));
    detail::Mat3 tau = mu * (F * materials::transpose(F));
    const double diag = lambda * logJ - mu;
    tau(0, 0) += diag;
    tau(1, 1) += diag;
    tau(2, 2) += diag;
    return tau;
  }
  static void stress(std::size_t n, const double* F, double mu, double lambda, double* tau) {
    for (std::size_t i = 0; i < n; ++i)
      detail::store3x3(tau_of(detail::load3x3(F + 9 * i), mu, lambda), tau + 9 * i);
  }
};

}  // namespace

void register_neo_hookean() {
  detail::add_model<Hyperelastic<NeoHookeanLaw>>(NeoHookeanLaw::kName);
}

}  // namespace gen4d::mpm
