//! Missing or misdirected gravity / body load: sets the deck's gravity (Physics::gravity), no
//! terms of its own.
#include "diagnose/effects/Helpers.hpp"

namespace gen4d::diagnose::effects {

namespace {

class Gravity final : public EffectBase {
 public:
  Gravity()
      : EffectBase({"gravity", "body acceleration (gx, gy, gz) other than the deck's gravity",
                    "static offset (sag) from the start; oscillation about a shifted mean"}) {}
  std::vector<ParamSpec> params(const EffectContext&, const std::string&) const override {
    return {{"gx", "m/s^2", -30, 30, false},
            {"gy", "m/s^2", -30, 30, false},
            {"gz", "m/s^2", -30, 30, false}};
  }
  Groups probe_groups(const EffectContext& c, const std::string&) const override {
    std::vector<std::vector<double>> g(3,
                                       {c.base.gravity[0], c.base.gravity[1], c.base.gravity[2]});
    for (int a = 0; a < 3; ++a) g[static_cast<std::size_t>(a)][static_cast<std::size_t>(a)] += 1.0;
    return {g};
  }
  bool scalable() const override { return true; }
  std::vector<double> null_values(const EffectContext& c, const std::string&) const override {
    return {c.base.gravity[0], c.base.gravity[1], c.base.gravity[2]};
  }
  void apply(const std::string&, const std::vector<double>& p, const EffectContext&,
             Physics& ph) const override {
    ph.gravity = {p[0], p[1], p[2]};
  }
};

}  // namespace

std::unique_ptr<Effect> make_gravity() {
  return std::make_unique<Gravity>();
}

}  // namespace gen4d::diagnose::effects
