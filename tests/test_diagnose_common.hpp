//! Helpers the diagnose tests share: effects set on a Physics by their term values
//! (Effect::apply's, without a scene context).
#pragma once

#include <string>

#include "diagnose/Effects.hpp"
#include "diagnose/Model.hpp"

namespace gen4d::diagnose::testing {

//! Rayleigh damping alpha M + beta K.
inline void set_damping(Physics& p, double alpha, double beta) {
  set_effect_terms(p, "damping", {alpha, beta});
}
//! One Prony term: fraction g relaxing with time tau.
inline void set_prony(Physics& p, double g, double tau) {
  set_effect_terms(p, "viscoelasticity", {g, tau});
}
inline void set_plasticity(Physics& p, double yield_stress, double hardening) {
  set_effect_terms(p, "plasticity", {yield_stress, hardening});
}
//! E times `factor` in `box`.
inline void set_region(Physics& p, const BoxRegion& box, double factor) {
  set_effect_terms(p, "heterogeneity",
                   {factor, box.lo[0], box.lo[1], box.lo[2], box.hi[0], box.hi[1], box.hi[2]});
}
//! Clamp springs and dashpots per unit clamp area.
inline void set_clamp(Physics& p, double stiffness, double damping) {
  set_effect_terms(p, "clamp_compliance", {stiffness, damping});
}
//! A ground plane z = height with Coulomb friction mu.
inline void set_ground(Physics& p, double height, double mu) {
  set_effect_terms(p, "contact_friction", {height, mu});
}
inline void set_drag(Physics& p, double linear, double quadratic) {
  set_effect_terms(p, "air_drag", {linear, quadratic});
}
inline void set_dry_friction(Physics& p, double accel) {
  set_effect_terms(p, "coulomb_damping", {accel});
}
//! Removes the effect called `name` from p.
inline void clear_effect(Physics& p, const std::string& name) {
  set_effect_terms(p, name, find_effect(name).absent_terms());
}

}  // namespace gen4d::diagnose::testing
