// MPM material registry: deck-value access, explicit registration of the built-in models,
// lookup with located input errors, and the common-key validation every model shares.
#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <utility>

#include <fmt/format.h>

#include "core/Error.hpp"
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
  auto& entries = table();
  if (entry.name.empty() || !entry.build)
    throw std::logic_error("register_material: entry needs a name and a build function");
  if (entries.count(entry.name))
    throw std::logic_error("MPM material '" + entry.name + "' registered twice");
  std::string name = entry.name;
  entries.emplace(std::move(name), std::move(entry));
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
  const auto& entries = registry();
  if (params.model.empty())
    throw InputError(fmt::format("{} is required (known models: {})", params.locate("model"),
                                 fmt::join(material_names(), ", ")));
  const auto it = entries.find(params.model);
  if (it == entries.end())
    throw InputError(fmt::format("{}: unknown model '{}' (known models: {})",
                                 params.locate("model"), params.model,
                                 fmt::join(material_names(), ", ")));
  const MaterialEntry& entry = it->second;

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
  std::vector<std::string> names;
  for (const auto& entry : registry()) names.push_back(entry.first);
  return names;
}

std::vector<std::string> material_keys(const std::string& name) {
  const auto& entries = registry();
  const auto it = entries.find(name);
  if (it == entries.end())
    throw InputError(fmt::format("unknown MPM material model '{}' (known models: {})", name,
                                 fmt::join(material_names(), ", ")));
  return it->second.keys;
}

}  // namespace gen4d::mpm
