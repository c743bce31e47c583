//! One box region of the body with a different stiffness. Terms: {factor, lo x y z, hi x y z}.
#include <cmath>

#include "diagnose/effects/Helpers.hpp"

namespace gen4d::diagnose::effects {

namespace {

class Heterogeneity final : public EffectBase {
 public:
  Heterogeneity()
      : EffectBase(
            {"heterogeneity",
             "one box region (located by the stiffness sensitivity map) with E times a factor",
             "mode-shape change and frequency shift; error concentrated near the region"}) {}
  bool applicable(const EffectContext& c) const override { return c.has_region; }
  std::vector<ParamSpec> params(const EffectContext&, const std::string&) const override {
    return {{"stiffness_factor", "", 0.05, 20.0, true}};
  }
  Groups probe_groups(const EffectContext&, const std::string&) const override { return {{{0.7}}}; }
  bool scalable() const override { return false; }
  std::vector<double> null_values(const EffectContext&, const std::string&) const override {
    return {1.0};
  }
  void apply(const std::string&, const std::vector<double>& p, const EffectContext& c,
             Physics& ph) const override {
    const BoxRegion& b = c.region;
    set_effect_terms(ph, *this, {p[0], b.lo[0], b.lo[1], b.lo[2], b.hi[0], b.hi[1], b.hi[2]});
  }
  void add_terms(const std::vector<double>& v, ModelTerms& t) const override {
    t.stiffness_boxes.push_back({{{v[1], v[2], v[3]}, {v[4], v[5], v[6]}}, v[0]});
  }
  int discrete_dof() const override { return 6; }
  std::vector<double> frequency_grid(const EffectContext&, const std::string&) const override {
    return {0.2, 0.35, 0.5, 0.7, 1.5, 2.5};  // region stiffness factors
  }
  // The body cut in quarters along its longest axis (snapped to voxels). The map's box is a
  // linearisation at the calibrated state, which has absorbed the region into E and nu: a
  // region stiffer than the rest can be located at the far side of the calibrated E, with the
  // opposite factor, and the face moves cannot cross from there.
  std::vector<BoxRegion> start_regions(const EffectContext& c) const override {
    const BoxRegion body = c.model->bounds();
    int ax = 0;
    for (int a = 1; a < 3; ++a)
      if (body.hi[a] - body.lo[a] > body.hi[ax] - body.lo[ax]) ax = a;
    const double h = c.model->h(), len = body.hi[ax] - body.lo[ax];
    std::vector<BoxRegion> out;
    for (int q = 0; q < 4; ++q) {
      BoxRegion b = body;
      b.lo[ax] = body.lo[ax] + h * std::round(q * len / (4 * h));
      b.hi[ax] = body.lo[ax] + h * std::round((q + 1) * len / (4 * h));
      if (b.hi[ax] - b.lo[ax] > 0.5 * h) out.push_back(b);
    }
    return out;
  }
};

}  // namespace

std::unique_ptr<Effect> make_heterogeneity() {
  return std::make_unique<Heterogeneity>();
}

}  // namespace gen4d::diagnose::effects
