// The law vocabulary (one table for every solver), deprecated spellings, and the voxel solvers'
// registry of pointwise laws.
#include "materials/Registry.hpp"

#include <algorithm>
#include <map>
#include <mutex>
#include <set>
#include <stdexcept>
#include <utility>

#include <fmt/format.h>

#include "core/Error.hpp"
#include "core/Log.hpp"

// Every pointwise law is included here, so that any program linking the registry also runs
// each law's registration line (a header nobody includes would never register).
#include "materials/Arap.hpp"
#include "materials/FixedCorotated.hpp"
#include "materials/LinearElastic.hpp"
#include "materials/NeoHookean.hpp"
#include "materials/StVK.hpp"

namespace gen4d::materials {

namespace {

constexpr const char* kHencky =
    "StVK in the Hencky strain e = log(Sigma): mu |e|^2 + lambda/2 tr(e)^2";
constexpr const char* kCorotated = "mu ||F - R||^2 + lambda/2 (J - 1)^2";

//! A row of the law table (plain data: constant-initialised, so the registrations that run
//! during static initialisation already see it).
struct Row {
  const char* name;
  const char* energy;
  const char* plastic;
  bool voxel, mpm;
};

//! The vocabulary: one row per energy (the deck name, the energy, the return map, the
//! solvers that provide it). A new law is one row here plus its implementation file.
constexpr Row kLaws[] = {
    {"fixed_corotated", kCorotated, "", true, true},
    {"stable_neo_hookean",
     "mu/2 (I_C - 3) + lambda/2 (J - alpha)^2 - mu/2 log(I_C + 1), alpha = 1 + 3 mu / (4 lambda)",
     "", true, false},
    {"neo_hookean", "mu/2 (tr(F^T F) - 3) - mu log J + lambda/2 (log J)^2", "", false, true},
    {"stvk", "StVK in the Green strain E: mu ||E||^2 + lambda/2 tr(E)^2", "", true, false},
    {"stvk_hencky", kHencky, "", false, true},
    {"linear", "mu ||eps||^2 + lambda/2 tr(eps)^2, eps = sym(F) - I", "", true, false},
    {"arap", "mu ||F - R||^2 (no volume term)", "", true, false},
    {"drucker_prager", kHencky, "Drucker-Prager cone, volume correction", false, true},
    {"von_mises", kHencky, "J2 radial return, linear or Johnson-Cook hardening", false, true},
    {"herschel_bulkley", kHencky, "viscoplastic J2 return (Herschel-Bulkley flow)", false, true},
    {"fracture", kCorotated, "tension damage from the largest Hencky strain", false, true},
    {"snow", kCorotated, "stretch clamp, moduli hardened by exp(xi (1 - J_P))", false, true},
};

//! An old spelling: `name` under `solver` means `law`.
struct Alias {
  const char* name;
  Solver solver;
  const char* law;
};

constexpr Alias kAliases[] = {
    {"corotated", Solver::Voxel, "fixed_corotated"},
    {"corotated", Solver::Mpm, "fixed_corotated"},
    {"neo_hookean", Solver::Voxel, "stable_neo_hookean"},
};

const char* solver_name(Solver s) {
  return s == Solver::Voxel ? "elastogen/newton/diagnose" : "mpm";
}

bool provides(const LawInfo& law, Solver s) {
  return s == Solver::Voxel ? law.voxel : law.mpm;
}

const Alias* find_alias(const std::string& name, Solver s) {
  for (const Alias& a : kAliases)
    if (a.solver == s && name == a.name) return &a;
  return nullptr;
}

// Function-local statics: registrations run during static initialisation of other translation
// units, in an order the language leaves open. The mutex guards run-time additions.
std::recursive_mutex& guard() {
  static std::recursive_mutex m;
  return m;
}
std::map<std::string, LawInfo>& vocabulary() {
  static std::map<std::string, LawInfo> table = [] {
    std::map<std::string, LawInfo> t;
    for (const Row& r : kLaws)
      t.emplace(r.name, LawInfo{r.name, r.energy, r.plastic, r.voxel, r.mpm});
    return t;
  }();
  return table;
}
std::map<std::string, MaterialDescriptor>& registry() {
  static std::map<std::string, MaterialDescriptor> table;
  return table;
}

}  // namespace

std::vector<LawInfo> laws() {
  std::lock_guard<std::recursive_mutex> lock(guard());
  std::vector<LawInfo> out;
  for (const auto& entry : vocabulary()) out.push_back(entry.second);
  return out;
}

std::vector<std::string> law_names(Solver solver) {
  std::vector<std::string> names;
  for (const LawInfo& law : laws())
    if (provides(law, solver)) names.push_back(law.name);
  for (const Alias& a : kAliases)
    if (a.solver == solver) names.push_back(a.name);
  std::sort(names.begin(), names.end());
  return names;
}

std::string canonical_law(const std::string& name, Solver solver, const std::string& where) {
  if (const Alias* a = find_alias(name, solver)) return a->law;
  {
    std::lock_guard<std::recursive_mutex> lock(guard());
    const auto it = vocabulary().find(name);
    if (it != vocabulary().end() && provides(it->second, solver)) return name;
  }
  throw InputError(fmt::format("{}unknown material '{}' for {}; known: {}",
                               where.empty() ? "" : where + ": ", name, solver_name(solver),
                               fmt::join(law_names(solver), ", ")));
}

std::string deprecation(const std::string& name, Solver solver) {
  const Alias* a = find_alias(name, solver);
  if (!a) return "";
  std::lock_guard<std::recursive_mutex> lock(guard());
  return fmt::format("material model '{}' is deprecated under {}: it is '{}' ({}); use that name",
                     name, solver_name(solver), a->law, vocabulary().at(a->law).energy);
}

std::string resolve_law(const std::string& name, Solver solver, const std::string& where) {
  std::string law = canonical_law(name, solver, where);
  if (law != name) {  // an old spelling: said once per process
    static std::set<std::pair<std::string, Solver>> said;
    bool first;
    {
      std::lock_guard<std::recursive_mutex> lock(guard());
      first = said.emplace(name, solver).second;
    }
    if (first && log::rank() == 0)
      log::warn("{}{}", where.empty() ? "" : where + ": ", deprecation(name, solver));
  }
  return law;
}

std::string deck_law(const std::string& name, Solver solver, const std::string& written_at) {
  if (written_at.empty()) return canonical_law(name, solver);
  return resolve_law(name, solver, written_at + ": material.model");
}

void declare_law(const std::string& name, Solver solver) {
  std::lock_guard<std::recursive_mutex> lock(guard());
  auto& table = vocabulary();
  auto it = table.find(name);
  if (it == table.end()) {
    LawInfo law{name, "(registered by the program)", "", solver == Solver::Voxel,
                solver == Solver::Mpm};
    table.emplace(name, std::move(law));
  } else if (!provides(it->second, solver)) {
    throw std::logic_error(
        fmt::format("law '{}' is not one the law table gives to {}", name, solver_name(solver)));
  }
}

bool register_material(MaterialDescriptor descriptor) {
  std::lock_guard<std::recursive_mutex> lock(guard());
  file_law(registry(), std::move(descriptor), Solver::Voxel, "register_material");
  return true;
}

const MaterialDescriptor& find_material(const std::string& name) {
  std::string law;
  try {
    law = canonical_law(name, Solver::Voxel);
  } catch (const InputError&) {
    throw InputError(
        fmt::format("unknown material '{}'; known: {}", name, fmt::join(known_materials(), ", ")));
  }
  std::lock_guard<std::recursive_mutex> lock(guard());
  auto& table = registry();
  const auto it = table.find(law);
  if (it == table.end())
    throw std::logic_error("law '" + law + "' has no pointwise implementation registered");
  if (law == name) return it->second;
  // An old spelling: the same law, built under the name it was asked for.
  auto spelled = table.find(name);
  if (spelled == table.end()) {
    MaterialDescriptor copy{name, [build = it->second.build, name](double E, double nu) {
                              MaterialInstance instance = build(E, nu);
                              instance.name = name;
                              return instance;
                            }};
    spelled = table.emplace(name, std::move(copy)).first;
  }
  return spelled->second;
}

std::vector<std::string> known_materials() {
  return law_names(Solver::Voxel);
}

}  // namespace gen4d::materials
