//! A support that gives in rotation but not in translation (a vise's jaws): the [[fixed]] nodes
//! on springs along their clamp face's normal, held in its plane. Terms: {normal stiffness per
//! unit clamp area}.
#include "diagnose/effects/Helpers.hpp"

namespace gen4d::diagnose::effects {

namespace {

class SupportRotation final : public CoefficientEffect {
 public:
  SupportRotation()
      : CoefficientEffect(
            {"support_rotation",
             "the [[fixed]] nodes on springs along the clamp face's normal only: the support "
             "turns, it does not slide",
             "lower frequencies, the first mode's most (a higher ratio of the second to the "
             "first), rotation at the support"},
            {&ModelTerms::clamp_normal_stiffness}) {}
  std::vector<ParamSpec> params(const EffectContext& c, const std::string&) const override {
    // As clamp_compliance's stiffness: compliant (1e-3 E/h) to rigid (1e4 E/h, the null value).
    const double k = c.base.youngs_modulus / c.model->h();
    return {{"normal_stiffness", "Pa/m", 1e-3 * k, 1e4 * k, true}};
  }
  Groups probe_groups(const EffectContext& c, const std::string&) const override {
    const double k = c.base.youngs_modulus / c.model->h();
    return {{{0.1 * k}}, {{1.0 * k}}, {{10.0 * k}}};
  }
  std::vector<double> null_values(const EffectContext& c, const std::string&) const override {
    return {1e4 * c.base.youngs_modulus / c.model->h()};
  }
  //! The calibration answers a softer support with a softer body: probed on the deck's E too.
  std::vector<Physics> probe_baselines(const EffectContext& c, const std::string&) const override {
    return deck_baseline(c, kDeckShiftNu, true, kDeckShiftE);
  }
  std::vector<double> frequency_grid(const EffectContext& c, const std::string&) const override {
    const double k = c.base.youngs_modulus / c.model->h();
    return {0.03 * k, 0.1 * k, 0.3 * k, 1.0 * k, 3.0 * k};
  }
  void apply(const std::string&, const std::vector<double>& p, const EffectContext& c,
             Physics& ph) const override {
    if (p[0] < 0.999e4 * c.base.youngs_modulus / c.model->h()) set_effect_terms(ph, *this, {p[0]});
  }
  bool in_default_library() const override { return false; }
};

}  // namespace

std::unique_ptr<Effect> make_support_rotation() {
  return std::make_unique<SupportRotation>();
}

}  // namespace gen4d::diagnose::effects
