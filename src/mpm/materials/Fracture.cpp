// fracture (tearing; PhysGaussian's "toast"/"bread" scenes): fixed-corotated elasticity with a
// scalar isotropic damage d in [0, 1] that only softens tension.
//
// History: eps_max = max over time of the largest principal Hencky strain log(sigma_0) of F
// (state slot 1, starts at 0). Damage (state slot 0), monotone non-decreasing:
//   d = max(d_old, clamp((eps_max - eps_c) / (eps_f - eps_c), 0, 1)),
// eps_c = fracture_strain (onset), eps_f = failure_strain (full damage).
// Stress: the fixed-corotated principal Kirchhoff stresses (F = U Sigma V^T, J = prod sigma_i)
//   t_i = 2 mu (sigma_i - 1) sigma_i + lambda (J - 1) J,
// split by sign, t_i <- (1 - d) t_i where t_i > 0; tau = U diag(t) U^T. Compression keeps the full
// stiffness, so broken material still resists interpenetration; at d = 1 a stretched piece carries
// no tension and separates. F is never modified (no plasticity).
// stress() uses max(state damage, damage of max(history, current eps)) so it agrees with update().
#include <algorithm>
#include <cmath>

#include "mpm/materials/Models.hpp"

namespace gen4d::mpm {

namespace {

using detail::Mat3;
using detail::Vec3;

struct FractureConstants {
  double mu, lambda;
  double eps_c, eps_f;
  double damage(double eps_max) const {
    return std::clamp((eps_max - eps_c) / (eps_f - eps_c), 0.0, 1.0);
  }
};

// tau of one particle; `history`/`damage` in: the stored state, out: the updated one.
inline Mat3 fracture_tau(const FractureConstants& c, const Mat3& U, const Vec3& s, double& damage,
                         double& history) {
  history = std::max(history, std::log(std::max(s[0], detail::kMinStretch)));
  damage = std::max(damage, c.damage(history));
  Vec3 t = detail::corotated_principal_tau(s, c.mu, c.lambda);
  for (int k = 0; k < 3; ++k) t[k] = t[k] > 0 ? (1 - damage) * t[k] : t[k];
  return detail::from_principal(U, t);
}

// update() of one particle: F is never changed (no plasticity).
inline void fracture_kernel(const FractureConstants& c, const Mat3& U, const Vec3& s, const Mat3&,
                            double*, double* state, double* taup, double) {
  detail::store3x3(fracture_tau(c, U, s, state[0], state[1]), taup);
}

using FractureBase = ReturnMap<ElasticBase, FractureConstants, fracture_kernel>;

class Fracture final : public FractureBase {
 public:
  explicit Fracture(const MaterialParams& p) : FractureBase(p) {
    c_.eps_c = p.get("fracture_strain");
    c_.eps_f = p.get("failure_strain");
    detail::check_value(p, "fracture_strain", c_.eps_c >= 0, ">= 0 (Hencky strain)");
    detail::check_value(p, "failure_strain", c_.eps_f > c_.eps_c,
                        "> material.fracture_strain (Hencky strain)");
  }
  std::string name() const override { return "fracture"; }
  std::vector<std::string> state_names() const override {
    return {"damage", "max_principal_strain"};
  }
  void stress(std::size_t n, const double* F, const double* state, double* tau) const override {
    detail::for_each_svd(n, F, [&](std::size_t i, const Mat3& U, const Vec3& s, const Mat3&) {
      double d = state[kStateSize * i], h = state[kStateSize * i + 1];
      detail::store3x3(fracture_tau(c_, U, s, d, h), tau + 9 * i);
    });
  }
};

}  // namespace

void register_fracture() {
  detail::add_model<Fracture>("fracture", {"fracture_strain", "failure_strain"});
}

}  // namespace gen4d::mpm
