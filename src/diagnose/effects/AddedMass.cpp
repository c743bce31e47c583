//! A rigid mass the deck does not declare (a bolted part, glue, a cable's share), at an unknown
//! place along the body's longest axis, spread over its cross-section. Terms: {mass (kg), the
//! place (m), the axis, the tent's half-width (m)}.
#include <algorithm>

#include "diagnose/effects/Helpers.hpp"

namespace gen4d::diagnose::effects {

namespace {

//! The body's longest axis.
int longest_axis(const BoxRegion& b) {
  int ax = 0;
  for (int a = 1; a < 3; ++a)
    if (b.hi[a] - b.lo[a] > b.hi[ax] - b.lo[ax]) ax = a;
  return ax;
}

class AddedMass final : public EffectBase {
 public:
  AddedMass()
      : EffectBase({"added_mass",
                    "a rigid mass at an unknown place along the body's longest axis (tent over "
                    "two cells, spread over the cross-section)",
                    "lower frequencies by mode (the modes moving most where it sits: the ratio of "
                    "the second frequency to the first changes, unlike a stiffness change)"}) {}
  std::vector<ParamSpec> params(const EffectContext& c, const std::string&) const override {
    const BoxRegion b = c.model->bounds();
    const int ax = longest_axis(b);
    return {{"mass", "kg", 1e-4 * c.total_mass, c.total_mass, true},
            {"position", "m", b.lo[ax], b.hi[ax], false, b.hi[ax] - b.lo[ax]}};
  }
  Groups probe_groups(const EffectContext& c, const std::string&) const override {
    const BoxRegion b = c.model->bounds();
    const int ax = longest_axis(b);
    Groups g;
    for (double f : {0.25, 0.5, 0.75, 1.0})
      g.push_back({{0.02 * c.total_mass, b.lo[ax] + f * (b.hi[ax] - b.lo[ax])}});
    return g;
  }
  std::vector<double> null_values(const EffectContext& c, const std::string&) const override {
    const BoxRegion b = c.model->bounds();
    return {1e-4 * c.total_mass, b.hi[longest_axis(b)]};
  }
  std::vector<double> frequency_grid(const EffectContext& c, const std::string&) const override {
    return {0.01 * c.total_mass, 0.03 * c.total_mass, 0.1 * c.total_mass, 0.3 * c.total_mass};
  }
  void apply(const std::string&, const std::vector<double>& p, const EffectContext& c,
             Physics& ph) const override {
    if (p[0] <= 1.001e-4 * c.total_mass) return;  // the null value: nothing added
    const BoxRegion b = c.model->bounds();
    set_effect_terms(ph, *this,
                     {p[0], p[1], static_cast<double>(longest_axis(b)), 2 * c.model->h()});
  }
  void add_terms(const std::vector<double>& v, ModelTerms& t) const override {
    ModelTerms::AddedMass m;
    const int ax = static_cast<int>(v[2]);
    m.mass = v[0];
    m.spread = {1e300, 1e300, 1e300};
    m.at[ax] = v[1];
    m.spread[ax] = v[3];
    t.added_masses.push_back(m);
  }
  bool in_default_library() const override { return false; }
};

}  // namespace

std::unique_ptr<Effect> make_added_mass() {
  return std::make_unique<AddedMass>();
}

}  // namespace gen4d::diagnose::effects
