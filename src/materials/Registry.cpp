// Material registry storage and lookup.
#include "materials/Registry.hpp"

#include <map>
#include <stdexcept>
#include <utility>

#include <fmt/format.h>

#include "core/Error.hpp"

// Every registered material is included here, so that any program linking the registry also runs
// each material's registration line (a header nobody includes would never register).
#include "materials/Arap.hpp"
#include "materials/FixedCorotated.hpp"
#include "materials/LinearElastic.hpp"
#include "materials/NeoHookean.hpp"
#include "materials/StVK.hpp"

namespace gen4d::materials {

namespace {

// Function-local static: registrations run during static initialisation of other translation
// units, in an order the language leaves open.
std::map<std::string, MaterialDescriptor>& registry() {
  static std::map<std::string, MaterialDescriptor> table;
  return table;
}

}  // namespace

bool register_material(MaterialDescriptor descriptor) {
  auto& table = registry();
  if (descriptor.name.empty() || !descriptor.build)
    throw std::logic_error("register_material: descriptor needs a name and a build function");
  if (table.count(descriptor.name))
    throw std::logic_error("material '" + descriptor.name + "' registered twice");
  std::string name = descriptor.name;
  table.emplace(std::move(name), std::move(descriptor));
  return true;
}

const MaterialDescriptor& find_material(const std::string& name) {
  const auto& table = registry();
  const auto it = table.find(name);
  if (it == table.end())
    throw InputError(
        fmt::format("unknown material '{}'; known: {}", name, fmt::join(known_materials(), ", ")));
  return it->second;
}

std::vector<std::string> known_materials() {
  std::vector<std::string> names;
  for (const auto& entry : registry()) names.push_back(entry.first);
  return names;
}

}  // namespace gen4d::materials
