//! The materials of one MPM run: slot 0 is the deck's [material] (or first [[material]]), slot k
//! its k-th later [[material]] entry; each particle names its slot (Particles::material).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "mpm/Material.hpp"

namespace gen4d::mpm {

class MaterialSet {
 public:
  MaterialSet() = default;
  //! One material for every particle.
  MaterialSet(std::shared_ptr<const Material> only);  // NOLINT(google-explicit-constructor)
  explicit MaterialSet(std::vector<std::shared_ptr<const Material>> slots);

  std::size_t size() const { return slots_.size(); }
  const Material& operator[](std::size_t slot) const { return *slots_.at(slot); }
  //! Largest elastic wave speed of all slots, whatever their state.
  double wave_speed() const;
  //! Largest Material::state_wave_speed of n particles by slot (the adaptive substep's bound).
  double state_wave_speed(std::size_t n, const std::uint8_t* slot, const double* state) const;
  //! The per-particle state names: the slot's own where every slot agrees, else the slots'
  //! names joined by "|" ("" for an unused slot), so a frame's fields name every meaning.
  std::vector<std::string> state_names() const;
  //! "name" for one material, "name1 + name2 + ..." for several.
  std::string describe() const;

  //! Material::update of n particles whose slots are `slot`: every run of equal slots is one
  //! batch of its material. InputError-free: a slot out of range is a std::logic_error.
  void update(std::size_t n, const std::uint8_t* slot, double* F, double* state, double* tau,
              double dt) const;
  //! Material::stress of n particles by slot.
  void stress(std::size_t n, const std::uint8_t* slot, const double* F, const double* state,
              double* tau) const;

 private:
  template <class Fn>
  void for_runs(std::size_t n, const std::uint8_t* slot, Fn&& fn) const;
  std::vector<std::shared_ptr<const Material>> slots_;
};

}  // namespace gen4d::mpm
