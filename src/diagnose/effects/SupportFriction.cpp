//! Amplitude-dependent (Coulomb) damping in a joint or clamp: dry friction on the nodes within
//! two cells of the support, a force of constant magnitude opposing their motion. Terms:
//! {friction acceleration a_c (m/s^2) of those nodes, the band's width (m)}.
#include <algorithm>
#include <cmath>

#include "diagnose/effects/Helpers.hpp"

namespace gen4d::diagnose::effects {

namespace {

//! On a node within `band` of the support: m a_c against the velocity at the step's start
//! (explicit in its direction, capped so it can at most stop the node).
class BandFriction final : public NodeForce {
 public:
  BandFriction(double accel, double band) : accel_(accel), band_(band) {}
  void add_residual(const ForceNode& n, const double*, const double v0[3], double dt,
                    double r[3]) const override {
    if (!(n.support_distance <= band_)) return;
    const double speed0 = std::sqrt(v0[0] * v0[0] + v0[1] * v0[1] + v0[2] * v0[2]);
    if (speed0 > 0)
      for (int d = 0; d < 3; ++d)
        r[d] += std::min(n.mass * accel_, n.mass * speed0 / dt) * v0[d] / speed0;
  }
  void apply_to_particle(const ForceNode&, double, double*, double&) const override {}

 private:
  double accel_, band_;
};

class SupportFriction final : public EffectBase {
 public:
  SupportFriction()
      : EffectBase({"support_friction",
                    "dry (Coulomb) friction on the nodes within two cells of the [[fixed]] "
                    "support: slip in a joint or clamp",
                    "decay faster at large amplitude than at small (linear envelope), no "
                    "frequency change"}) {}
  std::vector<ParamSpec> params(const EffectContext& c, const std::string&) const override {
    // The nodes by the support move about (2 h / L)^2 of the amplitude: their friction, in
    // units of what would stop them within a period, up to 100 times the body's own scale.
    return {{"friction_accel", "m/s^2", 0.0, 100 * c.omega * c.omega * std::max(c.amplitude, 1e-9),
             false, c.omega * c.omega * std::max(c.amplitude, 1e-9)}};
  }
  Groups probe_groups(const EffectContext& c, const std::string&) const override {
    return {{{0.1 * c.omega * c.omega * std::max(c.amplitude, 1e-9)}}};
  }
  bool scalable() const override { return true; }
  std::vector<double> null_values(const EffectContext&, const std::string&) const override {
    return {0};
  }
  std::vector<double> absent_terms() const override { return {0, 0}; }
  void apply(const std::string&, const std::vector<double>& p, const EffectContext& c,
             Physics& ph) const override {
    if (p[0] > 0) set_effect_terms(ph, *this, {p[0], 2 * c.model->h()});
  }
  void add_terms(const std::vector<double>& v, ModelTerms& t) const override {
    t.node_forces.push_back(std::make_shared<BandFriction>(v[0], v[1]));
  }
  bool in_default_library() const override { return false; }
};

}  // namespace

std::unique_ptr<Effect> make_support_friction() {
  return std::make_unique<SupportFriction>();
}

}  // namespace gen4d::diagnose::effects
