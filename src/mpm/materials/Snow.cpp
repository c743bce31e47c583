// snow (Stomakhin, Schroeder, Chai, Teran, Selle 2013, "A material point method for snow
// simulation"): fixed-corotated elasticity whose Lame parameters harden with plastic compaction,
// and plasticity that clamps the elastic stretches to a critical band.
//
// F = F_E F_P; the solver's F is F_E, the state keeps only J_P = det F_P (slot 0, starts at 1).
// Return map of the trial F_E = U Sigma V^T (signed SVD):
//   sigma_i <- clamp(sigma_i, 1 - theta_c, 1 + theta_s),  F_E <- U Sigma_clamped V^T,
//   F_P <- F_E^-1 F = V Sigma_clamped^-1 Sigma V^T F_P,  so J_P <- J_P prod(sigma_i / clamped_i)
// and J_E J_P = det F is unchanged. A trial F inside the band is left exactly as it is. An
// inverted (sigma_2 < 0) or collapsed trial stretch enters J_P as kMinStretch, so J_P stays
// positive.
// Stress (the seed's fixed corotated with hardened moduli), h = exp(xi (1 - J_P)):
//   tau = U diag(2 mu h (sigma_i - 1) sigma_i + lambda h (J_E - 1) J_E) U^T.
// Compaction (J_P < 1) stiffens, h <= exp(xi); stretching (J_P > 1) softens. The adaptive
// substep uses the hardening of the particles at hand (state_wave_speed: the smallest J_P, times
// one more full clamp (1 - theta_c)^3); the state-free bound wave_speed() is the largest one,
// J_P -> 0: sqrt(exp(xi) (lambda + 2 mu) / rho).
#include <algorithm>
#include <cmath>

#include "mpm/materials/Models.hpp"

namespace gen4d::mpm {

namespace {

using detail::Mat3;
using detail::Vec3;

//! Largest hardening coefficient: exp(xi) stays finite (and far from overflow) in the wave speed.
constexpr double kMaxHardeningCoefficient = 700.0;

struct SnowConstants {
  double mu, lambda;
  double lo, hi;  // 1 - theta_c, 1 + theta_s
  double xi;
  double hardening(double Jp) const { return std::exp(xi * (1.0 - Jp)); }
};

//! Fixed-corotated Kirchhoff stress of F_E = U diag(s) V^T with the moduli scaled by h.
inline Mat3 hardened_tau(const SnowConstants& c, const Mat3& U, const Vec3& s, double h) {
  return detail::from_principal(U, detail::corotated_principal_tau(s, c.mu * h, c.lambda * h));
}

inline void snow_kernel(const SnowConstants& c, const Mat3& U, Vec3 s, const Mat3& V, double* Fp,
                        double* state, double* taup, double /*dt: rate-independent*/) {
  bool clamped = false;
  double ratio = 1.0;
  for (int k = 0; k < 3; ++k) {
    const double clamped_k = std::clamp(s[k], c.lo, c.hi);
    if (clamped_k != s[k]) {
      clamped = true;
      ratio *= std::max(s[k], detail::kMinStretch) / clamped_k;
      s[k] = clamped_k;
    }
  }
  if (clamped) {
    state[0] *= ratio;
    detail::store3x3(materials::compose_svd(U, s, V), Fp);
  }
  detail::store3x3(hardened_tau(c, U, s, c.hardening(state[0])), taup);
}

using SnowBase = ReturnMap<ElasticBase, SnowConstants, snow_kernel>;

class Snow final : public SnowBase {
 public:
  explicit Snow(const MaterialParams& p) : SnowBase(p) {
    using detail::check_value;
    const double theta_c = p.get("critical_compression", 2.5e-2);
    const double theta_s = p.get("critical_stretch", 7.5e-3);
    c_.xi = p.get("hardening_coefficient", 10.0);
    if (p.has("critical_compression"))
      check_value(p, "critical_compression", theta_c >= 0 && theta_c < 1, "in [0, 1)");
    if (p.has("critical_stretch")) check_value(p, "critical_stretch", theta_s >= 0, ">= 0");
    if (p.has("hardening_coefficient"))
      check_value(p, "hardening_coefficient", c_.xi >= 0 && c_.xi <= kMaxHardeningCoefficient,
                  "in [0, 700]");
    c_.lo = 1.0 - theta_c;
    c_.hi = 1.0 + theta_s;
  }
  std::string name() const override { return "snow"; }
  std::vector<std::string> state_names() const override { return {"plastic_jacobian"}; }
  void init_state(double* state) const override {
    Material::init_state(state);
    state[0] = 1.0;
  }
  void stress(std::size_t n, const double* F, const double* state, double* tau) const override {
    detail::for_each_svd(n, F, [&](std::size_t i, const Mat3& U, const Vec3& s, const Mat3&) {
      detail::store3x3(hardened_tau(c_, U, s, c_.hardening(state[kStateSize * i])), tau + 9 * i);
    });
  }
  double wave_speed() const override {
    return std::sqrt(std::exp(c_.xi) * (lambda_ + 2 * mu_) / density_);
  }
  //! The hardening of the most compacted particle, compacted once more by a full clamp in each
  //! direction ((1 - theta_c)^3), which the next substep's return map could add.
  double state_wave_speed(std::size_t n, const double* state) const override {
    double jp = 1.0;
    for (std::size_t i = 0; i < n; ++i) jp = std::min(jp, state[kStateSize * i]);
    const double h = c_.hardening(std::max(0.0, jp * c_.lo * c_.lo * c_.lo));
    return std::sqrt(h * (lambda_ + 2 * mu_) / density_);
  }
};

}  // namespace

void register_snow() {
  detail::add_model<Snow>("snow",
                          {"critical_compression", "critical_stretch", "hardening_coefficient"});
}

}  // namespace gen4d::mpm
