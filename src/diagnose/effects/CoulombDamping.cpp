//! Dry friction: a force of constant magnitude m a_c opposing each node's velocity.
//! Terms: {a_c}.
#include <algorithm>
#include <cmath>

#include "diagnose/effects/Helpers.hpp"

namespace gen4d::diagnose::effects {

namespace {

//! On a node: against the velocity at the start of the step (explicit in its direction,
//! capped so it can at most stop the node: stable at any dt). On a particle: dt a_c taken off
//! the speed, never past zero.
class DryFriction final : public NodeForce {
 public:
  explicit DryFriction(double accel) : accel_(accel) {}
  void add_residual(const ForceNode& n, const double*, const double v0[3], double dt,
                    double r[3]) const override {
    const double speed0 = std::sqrt(v0[0] * v0[0] + v0[1] * v0[1] + v0[2] * v0[2]);
    if (speed0 > 0)
      for (int d = 0; d < 3; ++d)
        r[d] += std::min(n.mass * accel_, n.mass * speed0 / dt) * v0[d] / speed0;
  }
  void apply_to_particle(const ForceNode&, double dt, double v[3], double& speed) const override {
    if (speed > 0) {
      const double k = std::max(0.0, 1.0 - dt * accel_ / speed);
      for (int d = 0; d < 3; ++d) v[d] *= k;
      speed *= k;
    }
  }

 private:
  double accel_;
};

class CoulombDamping final : public EffectBase {
 public:
  CoulombDamping()
      : EffectBase(
            {"coulomb_damping", "dry friction: force m a_c opposing each node's velocity",
             "linear (amplitude-independent per cycle) decay, motion stops at a finite time"}) {}
  std::vector<ParamSpec> params(const EffectContext& c, const std::string&) const override {
    return {
        {"friction_accel", "m/s^2", 0.0, c.omega * c.omega * std::max(c.amplitude, 1e-9), false}};
  }
  Groups probe_groups(const EffectContext& c, const std::string&) const override {
    return {{{0.02 * c.omega * c.omega * std::max(c.amplitude, 1e-9)}}};
  }
  bool scalable() const override { return true; }
  std::vector<double> absent_terms() const override { return {0}; }
  void add_terms(const std::vector<double>& v, ModelTerms& t) const override {
    t.node_forces.push_back(std::make_shared<DryFriction>(v[0]));
  }
};

}  // namespace

std::unique_ptr<Effect> make_coulomb_damping() {
  return std::make_unique<CoulombDamping>();
}

}  // namespace gen4d::diagnose::effects
