//! The one vocabulary of constitutive laws (`material.model`) for every solver, and the voxel
//! solvers' registry of pointwise laws.
//
// Registry.cpp's law table names each energy once: its deck name, the energy, which solvers
// provide it and the return map of the plastic laws; deprecated spellings resolve to a law
// with a one-line warning. A solver's implementation registers under the table's name (the
// pointwise laws with `GEN4D_REGISTER_MATERIAL(Type);` after the struct, the MPM's models in
// mpm/materials/Registry.cpp); registering a name the table lacks adds it to the vocabulary.
// Kernels never go through the registry: they take the concrete material struct as a template
// parameter, picked once from the resolved name.
#pragma once

#include <functional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "materials/Mat3.hpp"

namespace gen4d::materials {

//! The solvers' families: the voxel ones (ElastoGen, the Newton reference, the `gen4d diagnose`
//! voxel model) share the pointwise laws; the MPM has its own models with return maps.
enum class Solver { Voxel, Mpm };

//! One row of the vocabulary.
struct LawInfo {
  std::string name;     //!< the deck name
  std::string energy;   //!< the elastic energy, one line
  std::string plastic;  //!< the return map ("" for elastic laws)
  bool voxel = false;   //!< provided by the voxel solvers
  bool mpm = false;     //!< provided by the MPM
};

//! Every law of the vocabulary (the built-in table, then laws registered at run time), sorted
//! by name.
std::vector<LawInfo> laws();

//! The law `name` means under `solver`: the name itself, or the law a deprecated spelling
//! stands for. InputError "WHERE: unknown material 'NAME' for SOLVER; known: ..." (the laws the
//! solver provides) otherwise. `where` locates the deck key ("" for none).
std::string canonical_law(const std::string& name, Solver solver, const std::string& where = "");

//! The one-line deprecation message of spelling `name` under `solver` (naming the law to use
//! instead), or "" when `name` is not deprecated there.
std::string deprecation(const std::string& name, Solver solver);

//! canonical_law, logging deprecation(name, solver) once per process (rank 0): the deck-facing
//! lookup.
std::string resolve_law(const std::string& name, Solver solver, const std::string& where = "");

//! The law of a deck's `material.model`: resolve_law (warning about an old spelling) where the
//! deck wrote the name at `written_at` ("FILE:LINE"), canonical_law for a default ("").
std::string deck_law(const std::string& name, Solver solver, const std::string& written_at);

//! Names `solver` accepts, sorted: its laws and the deprecated spellings that resolve to them.
std::vector<std::string> law_names(Solver solver);

//! Adds `name` to the vocabulary as a law of `solver` (logic_error where the table lists it
//! but not for that solver); how each solver's registry files its implementations.
void declare_law(const std::string& name, Solver solver);

//! Files a solver's implementation `entry` (with members `name` and `build`) in `table` under
//! its name, after declare_law: logic_error for an empty name, no build function or a second
//! entry under the name. `what` names the table in the messages.
template <class Table, class Entry>
void file_law(Table& table, Entry entry, Solver solver, const char* what) {
  if (entry.name.empty() || !entry.build)
    throw std::logic_error(std::string(what) + ": an entry needs a name and a build function");
  declare_law(entry.name, solver);
  if (table.count(entry.name))
    throw std::logic_error(std::string(what) + ": '" + entry.name + "' registered twice");
  std::string name = entry.name;
  table.emplace(std::move(name), std::move(entry));
}

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

//! Adds a voxel solvers' descriptor; a second descriptor under an existing name is a
//! programming error (std::logic_error). Returns true so it can initialise a registration
//! variable.
bool register_material(MaterialDescriptor descriptor);

//! The descriptor of the law `name` resolves to (canonical_law, no warning); InputError listing
//! the known names otherwise. The instance keeps the name it was asked for.
const MaterialDescriptor& find_material(const std::string& name);

//! Names find_material accepts (law_names(Solver::Voxel)), for messages and --help.
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
