// neo_hookean (PhysGaussian App. B.3; the seed lost the lambda in front of log J):
//   psi = mu/2 (tr(F^T F) - 3) - mu log J + lambda/2 (log J)^2,
//   tau = mu (F F^T - I) + lambda log(J) I,
// with J clamped at kMinStretch^3 so inverted particles get a large finite restoring pressure.
#include <algorithm>
#include <cmath>
#include <memory>

#include "mpm/materials/Models.hpp"

namespace gen4d::mpm {

namespace {

using detail::Mat3;

inline Mat3 neo_hookean_tau(const Mat3& F, double mu, double lambda) {
  constexpr double kMinJ = detail::kMinStretch * detail::kMinStretch * detail::kMinStretch;
  const double logJ = std::log(std::max(materials::det(F), kMinJ));
  Mat3 tau = mu * (F * materials::transpose(F));
  const double diag = lambda * logJ - mu;
  tau(0, 0) += diag;
  tau(1, 1) += diag;
  tau(2, 2) += diag;
  return tau;
}

class NeoHookean final : public ElasticBase {
 public:
  explicit NeoHookean(const MaterialParams& p) : ElasticBase(p) {}
  std::string name() const override { return "neo_hookean"; }
  std::vector<std::string> state_names() const override { return {}; }
  void update(std::size_t n, double* F, double*, double* tau, double) const override {
    stress(n, F, nullptr, tau);
  }
  void stress(std::size_t n, const double* F, const double*, double* tau) const override {
    for (std::size_t i = 0; i < n; ++i)
      detail::store3x3(neo_hookean_tau(detail::load3x3(F + 9 * i), mu_, lambda_), tau + 9 * i);
  }
};

}  // namespace

void register_neo_hookean() {
  detail::add_material_entry(
      {"neo_hookean", {}, [](const MaterialParams& p) { return std::make_unique<NeoHookean>(p); }});
}

}  // namespace gen4d::mpm
