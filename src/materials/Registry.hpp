//! Registry of constitutive models by the name decks use; each material registers itself.
//
// Adding a material is one header with one `GEN4D_REGISTER_MATERIAL(Type);` line after the
// struct, plus its #include in Registry.cpp (that include is what pulls the registration into
// every program linking the registry, as LAMMPS's generated style headers do). Kernels never go
// through the registry: they take the concrete material struct as a template parameter, picked
// once from MaterialInstance::name.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "materials/Mat3.hpp"

namespace gen4d::materials {

//! A material built from deck values, for host-side use (residual checks, reference solves).
struct MaterialInstance {
  std::string name;
  double youngs_modulus = 0;
  double poisson_ratio = 0;
  //! k of the projective-dynamics local model k/2 ||F - p||^2 (per unit volume, Pa).
  double projection_stiffness = 0;
  std::function<double(const Mat3&)> energy;  //!< energy density psi(F), J/m^3
  std::function<Mat3(const Mat3&)> pk1;       //!< first Piola-Kirchhoff stress dpsi/dF, Pa
};

//! What the registry stores per name.
struct MaterialDescriptor {
  std::string name;
  //! Validates (E, nu) (InputError on bad values) and builds the instance.
  std::function<MaterialInstance(double youngs_modulus, double poisson_ratio)> build;
};

//! Adds a descriptor; a second descriptor under an existing name is a programming error
//! (std::logic_error). Returns true so it can initialise a registration variable.
bool register_material(MaterialDescriptor descriptor);

//! The descriptor registered under `name`; InputError listing the known names otherwise.
const MaterialDescriptor& find_material(const std::string& name);

//! Registered names, sorted, for messages and --help.
std::vector<std::string> known_materials();

//! Descriptor of a material struct M that provides `name`, `from_young_poisson(E, nu)`,
//! `energy(F)`, `pk1(F)` and `projection_stiffness()`.
template <class M>
MaterialDescriptor describe_material() {
  return MaterialDescriptor{
      M::name, [](double youngs_modulus, double poisson_ratio) {
        const M material = M::from_young_poisson(youngs_modulus, poisson_ratio);
        MaterialInstance instance;
        instance.name = M::name;
        instance.youngs_modulus = youngs_modulus;
        instance.poisson_ratio = poisson_ratio;
        instance.projection_stiffness = material.projection_stiffness();
        instance.energy = [material](const Mat3& F) { return material.energy(F); };
        instance.pk1 = [material](const Mat3& F) { return material.pk1(F); };
        return instance;
      }};
}

}  // namespace gen4d::materials

//! Registers material struct `Type` under `Type::name`; use once, after the struct, inside
//! namespace gen4d::materials.
#define GEN4D_REGISTER_MATERIAL(Type) \
  inline const bool registered_material_##Type = register_material(describe_material<Type>())
