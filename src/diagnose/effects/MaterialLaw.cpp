//! Another hyperelastic law with the same E and nu: sets the deck's law (Physics::law), no
//! terms of its own.
#include "diagnose/effects/Helpers.hpp"

namespace gen4d::diagnose::effects {

namespace {

class MaterialLaw final : public EffectBase {
 public:
  MaterialLaw()
      : EffectBase(
            {"material_law",
             "another hyperelastic law (neo_hookean, stvk, corotated) with the same E, nu",
             "amplitude-dependent stiffness: static offset and frequency change at large strain"}) {
  }
  std::vector<std::string> variants(const EffectContext& c) const override {
    std::vector<std::string> v;
    for (const char* law : {"corotated", "neo_hookean", "stvk"})
      if (c.base.law != law) v.push_back(law);
    return v;
  }
  std::vector<ParamSpec> params(const EffectContext&, const std::string&) const override {
    return {};
  }
  Groups probe_groups(const EffectContext&, const std::string&) const override { return {{{}}}; }
  //! Fitted under the wrong law, nu can run far from the deck's, to a bound, where another
  //! law is a poor probe: when the calibration moved nu by more than kDeckNuProbeShift, the
  //! law is also probed at the deck's nu.
  std::vector<Physics> probe_baselines(const EffectContext& c, const std::string&) const override {
    return deck_baseline(c, kDeckNuProbeShift, false);
  }
  void apply(const std::string& variant, const std::vector<double>&, const EffectContext&,
             Physics& ph) const override {
    if (!variant.empty()) ph.law = variant;
  }
  static constexpr double kDeckNuProbeShift = 0.05;
  int discrete_dof() const override { return 1; }
};

}  // namespace

std::unique_ptr<Effect> make_material_law() {
  return std::make_unique<MaterialLaw>();
}

}  // namespace gen4d::diagnose::effects
