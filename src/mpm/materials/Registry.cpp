// MPM material registry: deck-value access, explicit registration of the built-in models,
// lookup with located input errors, and the common-key validation every model shares.
#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <utility>

#include <fmt/format.h>

#include "core/Error.hpp"
#include "materials/Registry.hpp"
#include "mpm/Material.hpp"
#include "mpm/materials/Models.hpp"

namespace gen4d::mpm {

namespace {

// Function-local static: no dependence on the initialisation order of translation units.
std::map<std::string, MaterialEntry>& table() {
  static std::map<std::string, MaterialEntry> entries;
  return entries;
}

// The built-in models, registered exactly once (thread-safe function-local static) before the
// first lookup or user registration. Each register_<model>() calls detail::add_material_entry,
// never register_material, so this does not recurse into itself.
std::map<std::string, MaterialEntry>& registry() {
  static const bool builtins = [] {
    register_fixed_corotated();
    register_stvk_hencky();
    register_neo_hookean();
    register_drucker_prager();
    register_von_mises();
    register_herschel_bulkley();
    register_fracture();
    register_snow();
    return true;
  }();
  (void)builtins;
  return table();
}

const char* const kCommonKeys[] = {"youngs_modulus", "poisson_ratio", "density"};

//! The entry of the law `name` resolves to (materials::resolve_law, which warns about an old
//! spelling when `warn`); InputError "WHERE: unknown model 'NAME' (known models: ...)".
const MaterialEntry& find_entry(const std::string& name, const std::string& where, bool warn) {
  const auto& entries = registry();
  std::string law;
  try {
    law = warn ? materials::resolve_law(name, materials::Solver::Mpm, where)
               : materials::canonical_law(name, materials::Solver::Mpm);
  } catch (const InputError&) {
    throw InputError(
        fmt::format("{}unknown {}model '{}' (known models: {})", where.empty() ? "" : where + ": ",
                    where.empty() ? "MPM material " : "", name, fmt::join(material_names(), ", ")));
  }
  const auto it = entries.find(law);
  if (it == entries.end())
    throw std::logic_error("MPM law '" + law + "' is in the law table but has no model");
  return it->second;
}

}  // namespace

double MaterialParams::get(const std::string& key) const {
  const auto it = values.find(key);
  if (it == values.end())
    throw InputError(fmt::format("{} is required for model {}", locate(key), model));
  return it->second;
}

double MaterialParams::get(const std::string& key, double fallback) const {
  const auto it = values.find(key);
  return it == values.end() ? fallback : it->second;
}

std::string MaterialParams::locate(const std::string& key) const {
  const auto it = where.find(key);
  const std::string& place = it != where.end() ? it->second : source;
  return fmt::format("{}: material.{}", place.empty() ? std::string("deck") : place, key);
}

void Material::init_state(double* state) const {
  for (int k = 0; k < kStateSize; ++k) state[k] = 0.0;
}

namespace detail {

void add_material_entry(MaterialEntry entry) {
  materials::file_law(table(), std::move(entry), materials::Solver::Mpm, "MPM register_material");
}

void check_value(const MaterialParams& params, const std::string& key, bool ok, const char* what) {
  if (!ok)
    throw InputError(
        fmt::format("{} must be {}, got {}", params.locate(key), what, params.get(key)));
}

}  // namespace detail

bool register_material(MaterialEntry entry) {
  registry();
  detail::add_material_entry(std::move(entry));
  return true;
}

std::unique_ptr<Material> make_material(const MaterialParams& params) {
  if (params.model.empty())
    throw InputError(fmt::format("{} is required (known models: {})", params.locate("model"),
                                 fmt::join(material_names(), ", ")));
  const MaterialEntry& entry = find_entry(params.model, params.locate("model"), true);

  // Every key must belong to the model, and be finite.
  for (const auto& [key, value] : params.values) {
    const bool common =
        std::find(std::begin(kCommonKeys), std::end(kCommonKeys), key) != std::end(kCommonKeys);
    const bool own = std::find(entry.keys.begin(), entry.keys.end(), key) != entry.keys.end();
    if (!common && !own)
      throw InputError(fmt::format(
          "{} is not a key of model {} (its keys: youngs_modulus, poisson_ratio, density{}{})",
          params.locate(key), entry.name, entry.keys.empty() ? "" : ", ",
          fmt::join(entry.keys, ", ")));
    if (!std::isfinite(value))
      throw InputError(
          fmt::format("{} must be a finite number, got {}", params.locate(key), value));
  }

  // Common keys: required by every model.
  const double E = params.get("youngs_modulus");
  const double nu = params.get("poisson_ratio");
  const double rho = params.get("density");
  detail::check_value(params, "youngs_modulus", E > 0, "> 0 (Pa)");
  detail::check_value(params, "poisson_ratio", nu > -1 && nu < 0.5, "in (-1, 0.5)");
  detail::check_value(params, "density", rho > 0, "> 0 (kg/m^3)");

  auto material = entry.build(params);
  if (!material) throw std::logic_error("MPM material '" + entry.name + "' built nothing");
  return material;
}

std::vector<std::string> material_names() {
  registry();
  return materials::law_names(materials::Solver::Mpm);
}

std::vector<std::string> material_keys(const std::string& name) {
  return find_entry(name, "", false).keys;
}

}  // namespace gen4d::mpm
