//! Standard linear solid: a fraction g of the stress relaxes with time constant tau.
//! Terms: {g, tau}.
#include "diagnose/effects/Helpers.hpp"

namespace gen4d::diagnose::effects {

namespace {

class Viscoelasticity final : public Effect {
 public:
  std::string name() const override { return "viscoelasticity"; }
  std::string summary() const override {
    return "one-term Prony series (standard linear solid): fraction g relaxes with time tau";
  }
  std::string signature() const override {
    return "frequency-dependent decay with a frequency shift; slow creep under a held load";
  }
  std::vector<ParamSpec> params(const EffectContext& c, const std::string&) const override {
    return {{"g", "", 0.0, 0.9, false}, {"tau", "s", 0.01 / c.omega, 100.0 / c.omega, true}};
  }
  Groups probe_groups(const EffectContext& c, const std::string&) const override {
    return {{{0.05, 0.1 / c.omega}}, {{0.05, 1.0 / c.omega}}, {{0.05, 10.0 / c.omega}}};
  }
  std::vector<double> null_values(const EffectContext& c, const std::string&) const override {
    return {0, 1.0 / c.omega};
  }
  void apply(const std::string&, const std::vector<double>& p, const EffectContext&,
             Physics& ph) const override {
    set_effect_terms(ph, *this, {p[0], p[1]});
  }
  std::vector<double> absent_terms() const override { return {0, 1}; }
  void add_terms(const std::vector<double>& v, ModelTerms& t) const override {
    t.prony_g = v[0];
    t.prony_tau = v[1];
  }
};

}  // namespace

std::unique_ptr<Effect> make_viscoelasticity() {
  return std::make_unique<Viscoelasticity>();
}

}  // namespace gen4d::diagnose::effects
