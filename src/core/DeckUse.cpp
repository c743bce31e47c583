#include "core/DeckUse.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <array>
#include <vector>

#include "core/Error.hpp"
#include "core/Log.hpp"

namespace gen4d {
namespace {

//! What a reader does with a table or key: reads it, accepts it unread with a warning, or
//! refuses it.
enum Use : char { R, W, X };

//! Columns of the table below.
enum Column { kElastogen, kNewton, kMpm, kDiagnoseVoxel, kDiagnoseMpm, kColumns };

//! One row: a table ("fixed") or a key ("output.surface"); a key's row overrides its table's.
//! Tables and keys without a row are read by everyone (their validity is checked by the
//! deck reader). Where the row refuses, `run` (a solver) or `diagnose` says what to use.
struct Row {
  const char* path;
  std::array<Use, kColumns> use;  //!< elastogen, newton, mpm, diagnose (voxel), diagnose (mpm)
  const char* run;
  const char* diagnose;
};

constexpr const char* kMpmSettings = "the MPM takes its settings from [mpm]";
constexpr const char* kMpmDiagnose = "an MPM deck takes [[boundary]] conditions";

// clang-format off
const Row kRows[] = {
    // The ElastoGen iteration's settings: the Newton reference and diagnose's implicit model
    // solve to their own tolerances.
    {"solver.relaxation",         {R, W, X, W, X}, kMpmSettings, kMpmSettings},
    {"solver.jacobi_omega",       {R, W, X, W, X}, kMpmSettings, kMpmSettings},
    {"solver.chebyshev_ratio",    {R, W, X, W, X}, kMpmSettings, kMpmSettings},
    {"solver.max_sweeps",         {R, W, X, W, X}, kMpmSettings, kMpmSettings},
    {"solver.inner_tolerance",    {R, W, X, W, X}, kMpmSettings, kMpmSettings},
    {"solver.subspace_modes",     {R, W, X, W, X}, kMpmSettings, kMpmSettings},
    {"solver.max_outer",          {R, W, X, W, X}, kMpmSettings, kMpmSettings},
    {"solver.outer_tolerance",    {R, W, X, W, X}, kMpmSettings, kMpmSettings},
    {"solver.max_extra_outer",    {R, W, X, W, X}, kMpmSettings, kMpmSettings},
    {"solver.anderson_depth",     {R, W, X, W, X}, kMpmSettings, kMpmSettings},
    {"solver.accuracy_tolerance", {R, R, X, W, X}, kMpmSettings, kMpmSettings},
    {"mpm",                       {X, X, R, X, R},
     "it applies to solver.method = \"mpm\"", "it applies to solver.method = \"mpm\""},
    {"boundary",                  {X, X, R, X, R},
     "it applies to solver.method = \"mpm\"; the voxel solvers use [[fixed]], [[kinematic]], "
     "[[force]], [[collider]] and [[traction]]",
     "it applies to solver.method = \"mpm\"; a voxel deck uses [[fixed]] and [[force]]"},
    {"fixed",                     {R, R, X, R, X},
     "the MPM takes [[boundary]] conditions: cuboid, surface_collider, particle_impulse, ...",
     kMpmDiagnose},
    {"kinematic",                 {R, R, X, X, X},
     "the MPM takes [[boundary]] conditions: cuboid (motion = \"moving\"), "
     "enforce_particle_translation, ...",
     "hold supports with [[fixed]]"},
    {"force",                     {R, R, X, R, X},
     "the MPM takes [[boundary]] type = \"particle_impulse\"", kMpmDiagnose},
    {"point_mass",                {R, R, R, R, R}, "", ""},
    {"attached_mass",             {R, R, R, R, R}, "", ""},
    {"force.curve",               {R, R, X, X, X},
     "the MPM takes [[boundary]] type = \"particle_impulse\"",
     "give the load history as [[force]] steps (start, end)"},
    {"traction",                  {R, R, X, X, X},
     "the MPM takes [[boundary]] type = \"particle_impulse\"",
     "give the load as a [[force]] region"},
    {"collider",                  {R, R, R, R, X}, "", "give obstacles as [[boundary]] surface_collider"},
    {"collider.lo",               {R, R, R, X, X}, "", "gen4d diagnose takes plane colliders"},
    {"collider.hi",               {R, R, R, X, X}, "", "gen4d diagnose takes plane colliders"},
    {"curve",                     {R, R, R, X, X}, "",
     "give the load history as [[force]] steps (start, end)"},
    {"output",                    {R, R, R, W, W}, "", ""},
    {"output.surface",            {R, R, X, W, W}, "the MPM writes output.particles", ""},
    {"output.surface_source",     {R, R, X, W, W}, "the MPM writes output.particles", ""},
    {"output.particles",          {X, X, R, W, W}, "the voxel solvers write output.surface", ""},
    {"output.volumes",            {X, X, R, W, W}, "the voxel solvers write output.surface", ""},
    {"render",                    {R, R, R, W, W}, "", ""},
    {"render.covariance_update",  {W, W, R, W, W}, "", ""},
};
// clang-format on

const char* user_name(Column c) {
  switch (c) {
    case kElastogen:
      return "solver.method = \"elastogen\"";
    case kNewton:
      return "solver.method = \"newton\"";
    case kMpm:
      return "solver.method = \"mpm\"";
    default:
      return "gen4d diagnose";
  }
}

Column column_of(const Config& c, DeckUser user) {
  switch (user) {
    case DeckUser::Elastogen:
      return kElastogen;
    case DeckUser::Newton:
      return kNewton;
    case DeckUser::Mpm:
      return kMpm;
    case DeckUser::Diagnose:
      break;
  }
  return c.solver.method == "mpm" ? kDiagnoseMpm : kDiagnoseVoxel;
}

//! The row of `path`, or null.
const Row* row_of(const std::string& path) {
  for (const Row& r : kRows)
    if (path == r.path) return &r;
  return nullptr;
}

//! The line of a "FILE:LINE" location, or a number past every line (--set, or no line).
long line_of(const std::string& where) {
  const auto colon = where.rfind(':');
  if (where.rfind("--set ", 0) == 0 || colon == std::string::npos) return 1L << 40;
  try {
    return std::stol(where.substr(colon + 1));
  } catch (const std::exception&) {
    return 1L << 40;
  }
}

bool is_array_table(const std::string& table) {
  for (const char* t : {"geometry", "material", "boundary", "fixed", "kinematic", "force",
                        "collider", "traction", "curve", "point_mass", "attached_mass"})
    if (table == t) return true;
  return false;
}

}  // namespace

DeckUser run_user(const Config& c) {
  if (c.solver.method == "mpm") return DeckUser::Mpm;
  if (c.solver.method == "newton") return DeckUser::Newton;
  return DeckUser::Elastogen;
}

void check_deck_use(const Config& c, DeckUser user) {
  const Column col = column_of(c, user);
  std::vector<std::string> warned;
  std::string warned_where, refused;
  long refused_line = 0;
  for (const auto& [path, where] : c.where) {
    const auto dot = path.find('.');
    const std::string table = path.substr(0, dot);
    const Row* row = row_of(path);
    if (!row && dot != std::string::npos) row = row_of(table);
    if (!row) continue;
    const Use use = row->use[col];
    if (use == R) continue;
    // A table refused or warned about is named once, at its header.
    if (dot != std::string::npos && row_of(table) == row) continue;
    const std::string name = dot == std::string::npos
                                 ? (is_array_table(table) ? "[[" + table + "]]" : "[" + table + "]")
                                 : "key '" + path + "'";
    if (use == W) {
      warned.push_back(name);
      if (warned_where.empty()) warned_where = where;
      continue;
    }
    // The first refusal in the file is the one reported.
    if (!refused.empty() && line_of(where) >= refused_line) continue;
    refused_line = line_of(where);
    const char* instead = col == kDiagnoseVoxel || col == kDiagnoseMpm ? row->diagnose : row->run;
    refused = fmt::format("{}: {} does not apply to {}{}", where, name, user_name(col),
                          *instead ? fmt::format(" ({})", instead) : "");
  }
  if (!refused.empty()) throw InputError(refused);
  if (!warned.empty())
    log::info(
        "warning: {}: {} not read by {}; accepted so the deck also serves the other "
        "commands",
        warned_where, fmt::format("{}", fmt::join(warned, ", ")), user_name(col));
}

}  // namespace gen4d
