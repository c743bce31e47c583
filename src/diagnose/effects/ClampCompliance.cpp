//! Elastic (and viscous) support instead of a rigid clamp. Terms: {stiffness, damping} per
//! unit clamp area.
#include "diagnose/effects/Helpers.hpp"

namespace gen4d::diagnose::effects {

namespace {

class ClampCompliance final : public CoefficientEffect {
 public:
  ClampCompliance()
      : CoefficientEffect(
            {"clamp_compliance",
             "the [[fixed]] nodes held by springs and dashpots per unit clamp area",
             "lower frequencies (mostly the first mode), motion at the support, mode-shape change"},
            {&ModelTerms::clamp_stiffness, &ModelTerms::clamp_damping}) {}
  std::vector<ParamSpec> params(const EffectContext& c, const std::string&) const override {
    // Stiffness from compliant (1e-3 E/h) to rigid (1e4 E/h, the null value). Damping up to
    // E/(h omega), a dashpot whose force at the dominant frequency is that of an E/h spring;
    // the optimiser works on it in units of 1 % of that. The bound also sets the fit's
    // finite-difference step (1e-3 of the range).
    const double k = c.base.youngs_modulus / c.model->h();
    return {{"stiffness", "Pa/m", 1e-3 * k, 1e4 * k, true},
            {"damping", "Pa s/m", 0.0, k / c.omega, false, 1e-2 * k / c.omega}};
  }
  Groups probe_groups(const EffectContext& c, const std::string&) const override {
    const double k = c.base.youngs_modulus / c.model->h();
    return {{{0.1 * k, 0}}, {{1.0 * k, 0}}, {{10.0 * k, 0}}};
  }
  std::vector<double> null_values(const EffectContext& c, const std::string&) const override {
    return {1e4 * c.base.youngs_modulus / c.model->h(), 0};
  }
  //! A compliant clamp lowers the first mode, and the calibration answers with a softer body,
  //! where the clamp probe screens poorly: it is also probed on the deck's E and nu.
  std::vector<Physics> probe_baselines(const EffectContext& c, const std::string&) const override {
    return deck_baseline(c, kDeckShiftNu, true, kDeckShiftE);
  }
  std::vector<double> frequency_grid(const EffectContext& c, const std::string&) const override {
    const double k = c.base.youngs_modulus / c.model->h();  // clamp stiffness per area, Pa/m
    return {0.03 * k, 0.1 * k, 0.3 * k, 1.0 * k, 3.0 * k};
  }
  void apply(const std::string&, const std::vector<double>& p, const EffectContext& c,
             Physics& ph) const override {
    if (p[0] < 0.999e4 * c.base.youngs_modulus / c.model->h())
      set_effect_terms(ph, *this, {p[0], p[1]});
  }
};

}  // namespace

std::unique_ptr<Effect> make_clamp_compliance() {
  return std::make_unique<ClampCompliance>();
}

}  // namespace gen4d::diagnose::effects
