//! Ground contact with Coulomb friction. Terms: {height, friction} of the plane z = height.
#include <algorithm>

#include "diagnose/effects/Helpers.hpp"

namespace gen4d::diagnose::effects {

namespace {

class ContactFriction final : public EffectBase {
 public:
  ContactFriction()
      : EffectBase({"contact_friction",
                    "a ground plane z = height (normal +z) with Coulomb friction",
                    "motion stops or flattens below a level; decay while sliding on the ground"}) {}
  std::vector<ParamSpec> params(const EffectContext& c, const std::string&) const override {
    const double a = std::max(c.amplitude, c.model->h());
    return {{"height", "m", c.lowest_point - 3 * a, c.lowest_point + 0.5 * a, false},
            {"friction", "", 0.0, 2.0, false}};
  }
  Groups probe_groups(const EffectContext& c, const std::string&) const override {
    const double a = std::max(c.amplitude, c.model->h());
    return {{{c.lowest_point, 0.3}}, {{c.lowest_point - 0.2 * a, 0.3}}};
  }
  //! A ground the deck leaves out stops the body where a free one would swing on: the
  //! calibration answers with a stiffer body, which then no longer reaches the recorded
  //! lowest point, so a plane there barely touches it. When the calibration moved E by more
  //! than kDeckShiftE or nu by more than kDeckShiftNu, the plane is also probed on the deck's
  //! E and nu.
  std::vector<Physics> probe_baselines(const EffectContext& c, const std::string&) const override {
    return deck_baseline(c, kDeckShiftNu, true, kDeckShiftE);
  }
  std::vector<double> null_values(const EffectContext& c, const std::string&) const override {
    return {c.lowest_point - 3 * std::max(c.amplitude, c.model->h()), 0};
  }
  void add_terms(const std::vector<double>& v, ModelTerms& t) const override {
    t.planes.push_back({{0, 0, v[0]}, {0, 0, 1}, v[1]});
  }
};

}  // namespace

std::unique_ptr<Effect> make_contact_friction() {
  return std::make_unique<ContactFriction>();
}

}  // namespace gen4d::diagnose::effects
