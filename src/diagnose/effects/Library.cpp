//! The effects of `gen4d diagnose`, in library order (screening and reports list them so).
#include <memory>
#include <vector>

#include "diagnose/Effects.hpp"

namespace gen4d::diagnose::effects {

// One line per effect: X(name) names the factory make_<name>() its file defines.
#define GEN4D_DIAGNOSE_EFFECTS(X) \
  X(damping)                      \
  X(viscoelasticity)              \
  X(plasticity)                   \
  X(material_law)                 \
  X(heterogeneity)                \
  X(gravity)                      \
  X(clamp_compliance)             \
  X(contact_friction)             \
  X(air_drag)                     \
  X(coulomb_damping)              \
  X(support_rotation)             \
  X(support_friction)             \
  X(added_mass)                   \
  X(sensor_mass)

#define GEN4D_DECLARE_EFFECT(name) std::unique_ptr<Effect> make_##name();
GEN4D_DIAGNOSE_EFFECTS(GEN4D_DECLARE_EFFECT)
#undef GEN4D_DECLARE_EFFECT

std::vector<std::unique_ptr<Effect>> builtin_effects() {
  std::vector<std::unique_ptr<Effect>> l;
#define GEN4D_ADD_EFFECT(name) l.push_back(make_##name());
  GEN4D_DIAGNOSE_EFFECTS(GEN4D_ADD_EFFECT)
#undef GEN4D_ADD_EFFECT
  return l;
}

}  // namespace gen4d::diagnose::effects
