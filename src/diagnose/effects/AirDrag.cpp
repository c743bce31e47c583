//! Aerodynamic drag on the exposed surface: per unit area -(linear v + quadratic |v| v).
//! Terms: {linear, quadratic}.
#include <algorithm>
#include <cmath>

#include "diagnose/effects/Helpers.hpp"

namespace gen4d::diagnose::effects {

namespace {

//! The drag on a node: its linear part as damping, its quadratic part in the residual; on a
//! particle, both implicit in the speed: v / (1 + dt (linear + quadratic |v|) a / m).
class Drag final : public NodeForce {
 public:
  Drag(double linear, double quadratic) : linear_(linear), quadratic_(quadratic) {}
  double damping(const ForceNode& n) const override { return linear_ * n.area; }
  void add_residual(const ForceNode& n, const double v1[3], const double*, double,
                    double r[3]) const override {
    if (quadratic_ == 0) return;
    const double speed = std::sqrt(v1[0] * v1[0] + v1[1] * v1[1] + v1[2] * v1[2]);
    for (int d = 0; d < 3; ++d) r[d] += quadratic_ * n.area * speed * v1[d];
  }
  void apply_to_particle(const ForceNode& n, double dt, double v[3], double& speed) const override {
    const double k = 1.0 / (1.0 + dt * (linear_ + quadratic_ * speed) * n.area / n.mass);
    for (int d = 0; d < 3; ++d) v[d] *= k;
    speed *= k;
  }

 private:
  double linear_, quadratic_;
};

class AirDrag final : public EffectBase {
 public:
  AirDrag()
      : EffectBase({"air_drag", "surface drag per exposed area: -(linear v + quadratic |v| v)",
                    "amplitude decay; quadratic part decays faster at large amplitude"}) {}
  std::vector<ParamSpec> params(const EffectContext& c, const std::string&) const override {
    const double b1 = unit_linear(c), b2 = b1 / std::max(c.max_speed, 1e-6);
    return {{"linear", "Pa s/m", 0.0, 25.0 * b1, false},
            {"quadratic", "kg/m^3", 0.0, 250.0 * b2, false}};
  }
  Groups probe_groups(const EffectContext& c, const std::string&) const override {
    const double b1 = unit_linear(c), b2 = b1 / std::max(c.max_speed, 1e-6);
    return {{{b1, 0.0}, {0.0, b2}}};
  }
  bool scalable() const override { return true; }
  std::vector<double> absent_terms() const override { return {0, 0}; }
  void add_terms(const std::vector<double>& v, ModelTerms& t) const override {
    t.node_forces.push_back(std::make_shared<Drag>(v[0], v[1]));
  }

 private:
  //! Linear drag equivalent to a 2 % damping ratio of the body as a whole.
  static double unit_linear(const EffectContext& c) {
    return 0.04 * c.omega * c.total_mass / std::max(c.surface_area, 1e-12);
  }
};

}  // namespace

std::unique_ptr<Effect> make_air_drag() {
  return std::make_unique<AirDrag>();
}

}  // namespace gen4d::diagnose::effects
