//! Von Mises plasticity with linear isotropic hardening. Terms: {yield stress (inf: none),
//! hardening}.
#include "diagnose/effects/Helpers.hpp"

namespace gen4d::diagnose::effects {

namespace {

class Plasticity final : public CoefficientEffect {
 public:
  Plasticity()
      : CoefficientEffect(
            {"plasticity", "von Mises yield with linear isotropic hardening (Hencky elasticity)",
             "permanent set after the load is removed; extra decay while yielding"},
            {&ModelTerms::yield_stress, &ModelTerms::hardening}) {}
  bool slow() const override { return true; }
  std::vector<ParamSpec> params(const EffectContext& c, const std::string&) const override {
    // Hardening in units of the probes' 0.02 E (in Pa, its steps left it where it started).
    return {{"yield_stress", "Pa", 0.05 * c.max_mises, 2.0 * c.max_mises, true},
            {"hardening", "Pa", 0.0, c.base.youngs_modulus, false, 0.02 * c.base.youngs_modulus}};
  }
  Groups probe_groups(const EffectContext& c, const std::string&) const override {
    const double H = 0.02 * c.base.youngs_modulus;
    return {{{0.4 * c.max_mises, H}}, {{0.6 * c.max_mises, H}}, {{0.8 * c.max_mises, H}}};
  }
  std::vector<double> null_values(const EffectContext& c, const std::string&) const override {
    return {2.0 * c.max_mises, 0};
  }
  void apply(const std::string&, const std::vector<double>& p, const EffectContext& c,
             Physics& ph) const override {
    std::vector<double> t = effect_terms(ph, *this);
    // At the upper bound nothing yields: keep the elastic law there (the null model).
    if (p[0] < 1.999 * c.max_mises) t[0] = p[0];
    t[1] = p[1];
    set_effect_terms(ph, *this, t);
  }
};

}  // namespace

std::unique_ptr<Effect> make_plasticity() {
  return std::make_unique<Plasticity>();
}

}  // namespace gen4d::diagnose::effects
