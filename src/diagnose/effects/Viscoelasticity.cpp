//! Standard linear solid: a fraction g of the stress relaxes with time constant tau.
//! Terms: {g, tau}.
#include "diagnose/effects/Helpers.hpp"

namespace gen4d::diagnose::effects {

namespace {

class Viscoelasticity final : public CoefficientEffect {
 public:
  Viscoelasticity()
      : CoefficientEffect(
            {"viscoelasticity",
             "one-term Prony series (standard linear solid): fraction g relaxes with time tau",
             "frequency-dependent decay with a frequency shift; slow creep under a held load"},
            {&ModelTerms::prony_g, &ModelTerms::prony_tau}) {}
  std::vector<ParamSpec> params(const EffectContext& c, const std::string&) const override {
    return {{"g", "", 0.0, 0.9, false}, {"tau", "s", 0.01 / c.omega, 100.0 / c.omega, true}};
  }
  Groups probe_groups(const EffectContext& c, const std::string&) const override {
    return {{{0.05, 0.1 / c.omega}}, {{0.05, 1.0 / c.omega}}, {{0.05, 10.0 / c.omega}}};
  }
  std::vector<double> null_values(const EffectContext& c, const std::string&) const override {
    return {0, 1.0 / c.omega};
  }
};

}  // namespace

std::unique_ptr<Effect> make_viscoelasticity() {
  return std::make_unique<Viscoelasticity>();
}

}  // namespace gen4d::diagnose::effects
