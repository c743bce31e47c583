//! The recording's accelerometers' own mass, where the deck leaves it out: the same mass at
//! each sensor's reference point (over the nodes of its cell). Terms: {mass (kg), then x, y, z
//! of each sensor, then the tent's half-width (m)}.
#include "diagnose/effects/Helpers.hpp"

namespace gen4d::diagnose::effects {

namespace {

class SensorMass final : public EffectBase {
 public:
  SensorMass()
      : EffectBase({"sensor_mass",
                    "each accelerometer's own mass at its reference point (one mass for all)",
                    "lower frequencies, most for the modes that move the sensors most"}) {}
  bool applicable(const EffectContext& c) const override { return !c.sensors.empty(); }
  std::vector<ParamSpec> params(const EffectContext& c, const std::string&) const override {
    return {{"mass", "kg", 1e-5 * c.total_mass, 0.3 * c.total_mass, true}};
  }
  Groups probe_groups(const EffectContext& c, const std::string&) const override {
    return {{{0.02 * c.total_mass}}};
  }
  std::vector<double> null_values(const EffectContext& c, const std::string&) const override {
    return {1e-5 * c.total_mass};
  }
  std::vector<double> frequency_grid(const EffectContext& c, const std::string&) const override {
    return {0.003 * c.total_mass, 0.01 * c.total_mass, 0.03 * c.total_mass, 0.1 * c.total_mass};
  }
  void apply(const std::string&, const std::vector<double>& p, const EffectContext& c,
             Physics& ph) const override {
    if (p[0] <= 1.001e-5 * c.total_mass) return;  // the null value: nothing added
    std::vector<double> terms = {p[0]};
    for (const Vec3d& X : c.sensors) terms.insert(terms.end(), X.begin(), X.end());
    terms.push_back(c.model->h());
    set_effect_terms(ph, *this, terms);
  }
  void add_terms(const std::vector<double>& v, ModelTerms& t) const override {
    const std::size_t sensors = (v.size() - 2) / 3;
    for (std::size_t k = 0; k < sensors; ++k) {
      ModelTerms::AddedMass m;
      m.mass = v[0];
      m.at = {v[1 + 3 * k], v[2 + 3 * k], v[3 + 3 * k]};
      m.spread = {v.back(), v.back(), v.back()};
      t.added_masses.push_back(m);
    }
  }
  bool in_default_library() const override { return false; }
};

}  // namespace

std::unique_ptr<Effect> make_sensor_mass() {
  return std::make_unique<SensorMass>();
}

}  // namespace gen4d::diagnose::effects
