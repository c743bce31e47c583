//! Rayleigh damping C = alpha M + beta K. Terms: {alpha, beta}.
#include "diagnose/effects/Helpers.hpp"

namespace gen4d::diagnose::effects {

namespace {

class Damping final : public CoefficientEffect {
 public:
  Damping()
      : CoefficientEffect(
            {"damping", "Rayleigh damping C = alpha M + beta K (mass- and stiffness-proportional)",
             "exponential amplitude decay (beta: faster for higher modes)"},
            {&ModelTerms::rayleigh_alpha, &ModelTerms::rayleigh_beta}) {}
  //! mass: C = alpha M; stiffness: C = beta K; rayleigh: both (one mode cannot tell them
  //! apart, so the one-term variants are tried too and BIC picks).
  std::vector<std::string> variants(const EffectContext&) const override {
    return {"mass", "stiffness", "rayleigh"};
  }
  std::vector<ParamSpec> params(const EffectContext& c, const std::string& v) const override {
    const ParamSpec a{"alpha", "1/s", 0.0, c.omega, false},
        b{"beta", "s", 0.0, 1.0 / c.omega, false};
    if (v == "mass") return {a};
    if (v == "stiffness") return {b};
    return {a, b};
  }
  Groups probe_groups(const EffectContext& c, const std::string& v) const override {
    if (v == "mass") return {{{0.04 * c.omega}}};
    if (v == "stiffness") return {{{0.04 / c.omega}}};
    return {{{0.04 * c.omega, 0.0}, {0.0, 0.04 / c.omega}}};
  }
  bool scalable() const override { return true; }
  std::vector<double> null_values(const EffectContext&, const std::string& v) const override {
    return v == "rayleigh" ? std::vector<double>{0, 0} : std::vector<double>{0};
  }
  void apply(const std::string& v, const std::vector<double>& p, const EffectContext&,
             Physics& ph) const override {
    std::vector<double> t = effect_terms(ph, *this);
    if (v == "mass")
      t[0] = p[0];
    else if (v == "stiffness")
      t[1] = p[0];
    else
      t = {p[0], p[1]};
    set_effect_terms(ph, *this, t);
  }
};

}  // namespace

std::unique_ptr<Effect> make_damping() {
  return std::make_unique<Damping>();
}

}  // namespace gen4d::diagnose::effects
