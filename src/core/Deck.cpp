#include "core/Deck.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/DeckReader.hpp"
#include "core/DeckUse.hpp"
#include "core/Error.hpp"
#include "core/TextFile.hpp"

namespace gen4d {
namespace {

namespace fs = std::filesystem;
using deck::Locator;
using deck::Section;

void require_positive(const Section& s, std::string_view key, double v) {
  s.check(v > 0, key, fmt::format("must be > 0, got {}", v));
}

void require_at_least(const Section& s, std::string_view key, double v, double min) {
  s.check(v >= min, key, fmt::format("must be >= {}, got {}", min, v));
}

//! Boxes must have volume: a flat or inverted box selects nothing, which is never intended.
void require_box(const Section& s, const Vec3d& lo, const Vec3d& hi) {
  for (int d = 0; d < 3; ++d)
    s.check(lo[d] < hi[d], "hi",
            fmt::format("must be > lo in every component, got lo = {}, hi = {}", lo, hi));
}

//! `lo` and `hi`, checked to form a box.
BoxRegion read_box(const Section& s) {
  BoxRegion r;
  r.lo = s.vec3("lo");
  r.hi = s.vec3("hi");
  require_box(s, r.lo, r.hi);
  return r;
}

//! `start` (>= 0) and `end` (> start) of an active window; absent keys keep their defaults.
void read_window(const Section& s, double& start, double& end, bool preload = false) {
  start = s.number("start", start);
  if (!preload) require_at_least(s, "start", start, 0);
  end = s.number("end", end);
  s.check(end > start, "end", fmt::format("must be > start ({}), got {}", start, end));
}

std::vector<std::string> key_names(std::string_view table) {
  std::vector<std::string> out;
  for (const auto& k : deck::find_table(table)->keys) out.emplace_back(k.name);
  return out;
}

//! Rejects top-level keys that are not tables of the schema.
void reject_unknown_tables(const toml::table& root, const Locator& loc) {
  std::vector<std::string> tables;
  for (const auto& t : deck::schema()) tables.emplace_back(t.name);
  const toml::node* first = nullptr;
  std::string name;
  for (auto&& [key, value] : root) {
    if (deck::find_table(key.str())) continue;
    if (!first || value.source().begin.line < first->source().begin.line) {
      first = &value;
      name = std::string(key.str());
    }
  }
  if (!first) return;
  std::string hint = deck::suggestion(name, tables);
  // A key written above every table header ("dt = 0.1") belongs in one of the tables.
  for (const auto& t : deck::schema())
    if (hint.empty() && t.find(name))
      hint = fmt::format(" (did you mean '{}.{}' under [{}]?)", t.name, name, t.name);
  throw InputError(fmt::format("{}: unknown {} '{}'{}", loc.at(first, name),
                               first->is_table() || first->is_array_of_tables() ? "table" : "key",
                               name, hint));
}

//! The [name] table, or an absent section when the deck has none.
Section table_section(toml::table& root, const std::string& name, const Locator& loc) {
  toml::node* node = root.get(name);
  if (node && !node->is_table())
    loc.fail(node, name,
             fmt::format("expected a table [{}], got {}", name, deck::type_name(*node)));
  const std::vector<std::string> keys = key_names(name);
  Section s(loc, node ? node->as_table() : nullptr, name, node);
  s.reject_unknown(keys);
  return s;
}

//! One section per [[name]] table, in file order.
std::vector<Section> array_sections(toml::table& root, const std::string& name,
                                    const Locator& loc) {
  std::vector<Section> out;
  toml::node* node = root.get(name);
  if (!node) return out;
  toml::array* arr = node->as_array();
  if (!arr || (!arr->empty() && !arr->is_array_of_tables()))
    loc.fail(node, name,
             fmt::format("expected an array of tables [[{}]], got {}", name,
                         arr ? "an array of values" : deck::type_name(*node)));
  for (std::size_t i = 0; i < arr->size(); ++i) {
    toml::table* t = arr->get_as<toml::table>(i);
    out.emplace_back(loc, t, fmt::format("{}.{}", name, i), t);
  }
  return out;
}

void read_simulation(const Section& s, Config& c) {
  c.name = s.string("name", c.name);
  s.check(!c.name.empty(), "name", "must not be empty");
  c.dt = s.number("dt");
  require_positive(s, "dt", c.dt);
  c.end_time = s.number("end_time");
  s.check(c.end_time >= c.dt, "end_time",
          fmt::format("must be >= simulation.dt ({}), got {}", c.dt, c.end_time));
  c.gravity = s.vec3("gravity", c.gravity);
}

void read_domain(const Section& s, Config& c) {
  const toml::node* size = s.node("voxel_size");
  if (size && size->is_array()) {
    c.spacing = s.vec3("voxel_size");
    for (int a = 0; a < 3; ++a)
      s.check(c.spacing[a] > 0, "voxel_size",
              fmt::format("every cell edge must be > 0, got {}", c.spacing));
  } else {
    const double h = s.number("voxel_size");
    require_positive(s, "voxel_size", h);
    c.spacing = {h, h, h};
  }
  c.voxel_size = std::max({c.spacing[0], c.spacing[1], c.spacing[2]});
  c.padding = s.integer("padding", c.padding);
  require_at_least(s, "padding", c.padding, 0);
}

std::vector<std::string> geometry_keys(const std::string& type) {
  if (type == "box") return {"type", "name", "lo", "hi", "color"};
  if (type == "sphere") return {"type", "name", "center", "radius", "color"};
  if (type == "capsule" || type == "cylinder") return {"type", "name", "a", "b", "radius", "color"};
  if (type == "mesh") return {"type", "name", "file", "scale", "translate", "color"};
  if (type == "splats")
    return {"type",      "name",        "file",           "scale",
            "translate", "rotate_axis", "rotate_degrees", "opacity_threshold",
            "fill_cells"};
  return {"type", "name", "file", "grid", "scale", "translate", "color"};  // vdb
}

//! Rejects keys of `table` that exist for some of its types but not for `type` (keys `own`).
void reject_foreign_keys(const Section& s, std::string_view table, const std::string& type,
                         const std::vector<std::string>& own) {
  const toml::node* first = nullptr;
  std::string first_key;
  for (const std::string& key : key_names(table)) {
    const toml::node* n = s.node(key);
    if (!n || std::find(own.begin(), own.end(), key) != own.end()) continue;
    if (!first || n->source().begin.line < first->source().begin.line) {
      first = n;
      first_key = key;
    }
  }
  if (first)
    s.fail(first_key, fmt::format("not a key of {} type '{}' (its keys: {})", table, type,
                                  fmt::join(own, ", ")));
}

//! Rejects keys that exist for some geometry type but not for this one.
void reject_foreign_geometry_keys(const Section& s, const std::string& type) {
  reject_foreign_keys(s, "geometry", type, geometry_keys(type));
}

//! `file` resolved against the deck's folder; InputError on `key` ("MISSING: PATH") unless it is
//! a regular file. The deck's `key` becomes the absolute path plus `suffix`, so the final deck
//! text stays valid wherever it is re-read (restarts).
std::string resolve_existing(Section& s, std::string_view key, const std::string& file,
                             const fs::path& base_dir, std::string_view missing = "file not found",
                             const std::string& suffix = "") {
  const fs::path path = fs::absolute(base_dir / fs::path(file)).lexically_normal();
  std::error_code ec;
  s.check(fs::is_regular_file(path, ec), key, fmt::format("{}: {}", missing, path.string()));
  s.replace(key, path.string() + suffix);
  return path.string() + suffix;
}

//! Resolves `file` against the deck's folder, checks it, and stores the absolute path so the
//! final deck text stays valid wherever it is re-read (restarts).
std::string resolve_file(Section& s, const fs::path& base_dir, bool mesh) {
  const std::string file = s.string("file");
  s.check(!file.empty(), "file", "must not be empty");
  if (mesh) {
    std::string ext = fs::path(file).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
    s.check(ext == ".obj" || ext == ".stl", "file",
            fmt::format("must be an .obj or .stl file, got '{}'", file));
  }
  return resolve_existing(s, "file", file, base_dir);
}

void require_nonzero_vector(const Section& s, std::string_view key, const Vec3d& v) {
  s.check(v[0] * v[0] + v[1] * v[1] + v[2] * v[2] > 0, key,
          fmt::format("must not be the zero vector, got {}", v));
}

//! Colour channels in [0, 1].
void require_unit_colour(const Section& s, std::string_view key, const Vec3d& c) {
  for (double x : c)
    s.check(x >= 0 && x <= 1, key, fmt::format("colour channels must be in [0, 1], got {}", c));
}

GeometryConfig read_geometry(Section& s, const fs::path& base_dir) {
  GeometryConfig g;
  s.string("type");  // presence and type first, then the value
  g.type = s.choice("type", "", {"box", "sphere", "capsule", "cylinder", "mesh", "vdb", "splats"});
  reject_foreign_geometry_keys(s, g.type);
  g.name = s.string("name", g.name);
  if (g.type == "box") {
    g.lo = s.vec3("lo");
    g.hi = s.vec3("hi");
    require_box(s, g.lo, g.hi);
  } else if (g.type == "sphere") {
    g.center = s.vec3("center");
    g.radius = s.number("radius");
    require_positive(s, "radius", g.radius);
  } else if (g.type == "capsule" || g.type == "cylinder") {
    g.a = s.vec3("a");
    g.b = s.vec3("b");
    g.radius = s.number("radius");
    require_positive(s, "radius", g.radius);
    if (g.type == "cylinder")
      s.check(g.a != g.b, "b", fmt::format("must differ from a (the axis), got {}", g.b));
  } else {
    g.file = resolve_file(s, base_dir, g.type == "mesh");
    if (g.type == "vdb") g.grid = s.string("grid", g.grid);
    g.scale = s.number("scale", g.scale);
    require_positive(s, "scale", g.scale);
    g.translate = s.vec3("translate", g.translate);
  }
  if (g.type == "splats") {
    g.rotate_axis = s.vec3("rotate_axis", g.rotate_axis);
    require_nonzero_vector(s, "rotate_axis", g.rotate_axis);
    g.rotate_degrees = s.number("rotate_degrees", g.rotate_degrees);
    g.opacity_threshold = s.number("opacity_threshold", g.opacity_threshold);
    s.check(g.opacity_threshold >= 0 && g.opacity_threshold < 1, "opacity_threshold",
            fmt::format("must be in [0, 1), got {}", g.opacity_threshold));
    g.fill_cells = s.integer("fill_cells", g.fill_cells);
    s.check(g.fill_cells >= 0 && g.fill_cells <= 4096, "fill_cells",
            fmt::format("must be in [0, 4096] (0: no filling), got {}", g.fill_cells));
  } else {
    g.color = s.vec3("color", g.color);
    require_unit_colour(s, "color", g.color);
  }
  return g;
}

void read_geometries(toml::table& root, const Locator& loc, const fs::path& base_dir, Config& c) {
  const toml::node* node = root.get("geometry");
  if (!node)
    throw InputError(fmt::format("{}: missing required key 'geometry' (add a [[geometry]] table)",
                                 loc.at(nullptr, "geometry")));
  std::vector<Section> sections = array_sections(root, "geometry", loc);
  if (sections.empty()) loc.fail(node, "geometry", "at least one [[geometry]] table is required");
  for (Section& s : sections) {
    s.reject_unknown(key_names("geometry"));
    c.geometry.push_back(read_geometry(s, base_dir));
    const std::string& name = c.geometry.back().name;
    if (s.has("name")) s.check(!name.empty(), "name", "must not be empty");
    for (std::size_t i = 0; i + 1 < c.geometry.size() && !name.empty(); ++i)
      s.check(c.geometry[i].name != name, "name",
              fmt::format("'{}' already names geometry.{}", name, i));
  }
}

//! Keys of [material] that only MPM models take (validated per model by the MPM registry).
const std::vector<std::string>& mpm_material_keys() {
  static const std::vector<std::string> keys = {"friction_angle",
                                                "cohesion",
                                                "yield_stress",
                                                "hardening",
                                                "jc_A",
                                                "jc_B",
                                                "jc_n",
                                                "jc_C",
                                                "jc_m",
                                                "reference_strain_rate",
                                                "room_temperature",
                                                "melt_temperature",
                                                "initial_temperature",
                                                "specific_heat",
                                                "taylor_quinney",
                                                "consistency",
                                                "flow_index",
                                                "fracture_strain",
                                                "failure_strain",
                                                "critical_compression",
                                                "critical_stretch",
                                                "hardening_coefficient"};
  return keys;
}

void read_elastic_constants(const Section& s, MaterialConfig& m) {
  m.youngs_modulus = s.number("youngs_modulus");
  require_positive(s, "youngs_modulus", m.youngs_modulus);
  m.poisson_ratio = s.number("poisson_ratio");
  s.check(m.poisson_ratio > -1 && m.poisson_ratio < 0.5, "poisson_ratio",
          fmt::format("must be in (-1, 0.5), got {}", m.poisson_ratio));
  m.density = s.number("density");
  require_positive(s, "density", m.density);
}

void read_mpm_material(Section& s, MaterialConfig& m) {
  m.model = s.string("model");
  m.param_where["model"] = s.where("model");
  for (const char* key : {"target", "neural_weights"})
    s.check(!s.has(key), key, "does not apply to solver.method = \"mpm\"");
  read_elastic_constants(s, m);
  for (const std::string& key : mpm_material_keys()) {
    if (!s.has(key)) continue;
    m.params[key] = s.number(key);
    m.param_where[key] = s.where(key);
  }
  // At or above the melt temperature Johnson-Cook's yield stress is zero or negative.
  const auto melt = m.params.find("melt_temperature");
  if (melt != m.params.end() && s.has("initial_temperature"))
    s.check(m.params["initial_temperature"] < melt->second, "initial_temperature",
            fmt::format("must be below melt_temperature ({} K; the metal would start molten), "
                        "got {}",
                        melt->second, m.params["initial_temperature"]));
}

void read_material(Section& s, MaterialConfig& m, const fs::path& base_dir) {
  for (const std::string& key : mpm_material_keys())
    s.check(!s.has(key), key, "only applies to solver.method = \"mpm\"");
  // The voxel laws of materials/Registry.cpp's table, and their deprecated spellings.
  m.model = s.choice(
      "model", m.model,
      {"fixed_corotated", "stable_neo_hookean", "stvk", "linear", "corotated", "neo_hookean"});
  if (s.has("model")) m.param_where["model"] = s.where("model");  // for the law's warnings
  m.target = s.choice("target", m.target, {"analytic", "arap", "neural"});
  if (m.target == "neural") {
    s.check(m.model != "linear", "model",
            "target = \"neural\" needs a hyperelastic law (corotated, neo_hookean or stvk)");
    if (s.has("neural_weights")) {
      const std::string file = s.string("neural_weights");
      s.check(!file.empty(), "neural_weights", "must not be empty (leave it out to generate)");
      m.neural_weights = resolve_existing(s, "neural_weights", file, base_dir);
    }
  } else {
    s.check(!s.has("neural_weights"), "neural_weights", "only applies to target = \"neural\"");
  }
  read_elastic_constants(s, m);
}

constexpr const char* kBindingKeys[] = {"geometry", "lo", "hi"};

//! The binding of a [[material]] entry after the first: `geometry = NAME` or `lo`/`hi`.
void read_material_binding(const Section& s, const Config& c, MaterialConfig& m) {
  const bool named = s.has("geometry"), boxed = s.has("lo") || s.has("hi");
  if (named == boxed)
    s.fail_table(named ? "takes geometry or lo/hi, not both"
                       : "a [[material]] after the first needs a binding: geometry = NAME (a "
                         "named [[geometry]] part) or lo/hi (a box of rest positions)");
  if (named) {
    m.geometry = s.string("geometry");
    std::vector<std::string> names;
    for (std::size_t i = 0; i < c.geometry.size(); ++i) {
      if (c.geometry[i].name == m.geometry) m.geometry_part = static_cast<int>(i);
      if (!c.geometry[i].name.empty()) names.push_back("'" + c.geometry[i].name + "'");
    }
    s.check(m.geometry_part >= 0, "geometry",
            fmt::format("no [[geometry]] part is named '{}' (named parts: {})", m.geometry,
                        names.empty() ? "none; give one a name key"
                                      : fmt::format("{}", fmt::join(names, ", "))));
  } else {
    m.region = read_box(s);
    m.has_region = true;
  }
}

//! [material] (one material) or [[material]] (the first for everything, each later one for the
//! part or box it names; the voxel solver needs one model and target for all of them).
void read_materials(toml::table& root, const Locator& loc, const fs::path& base_dir, Config& c) {
  const toml::node* node = root.get("material");
  std::vector<Section> sections;
  if (node && node->is_array()) {
    sections = array_sections(root, "material", loc);
    if (sections.empty()) loc.fail(node, "material", "at least one [[material]] table is required");
  } else {
    sections.push_back(table_section(root, "material", loc));
  }
  const bool repeated = node && node->is_array();
  for (std::size_t i = 0; i < sections.size(); ++i) {
    Section& s = sections[i];
    s.reject_unknown(key_names("material"));
    MaterialConfig m;
    if (c.solver.method == "mpm")
      read_mpm_material(s, m);
    else
      read_material(s, m, base_dir);
    m.where = s.where("model");
    if (i == 0) {
      for (const char* key : kBindingKeys)
        s.check(!s.has(key), key,
                repeated ? "the first [[material]] is the material of everything the later ones "
                           "do not claim; it takes no binding"
                         : "binds a [[material]] entry after the first; a single [material] "
                           "table applies to everything");
      c.material = m;
      continue;
    }
    read_material_binding(s, c, m);
    if (c.solver.method == "newton")
      s.fail_table(
          "several [[material]] entries need solver.method = \"elastogen\" or \"mpm\" (the "
          "Newton reference takes one material)");
    if (c.solver.method != "mpm") {
      s.check(m.model == c.material.model, "model",
              fmt::format("the voxel solver needs one law for every [[material]] ('{}' in the "
                          "first); they may differ in youngs_modulus, poisson_ratio and density",
                          c.material.model));
      s.check(m.target == c.material.target, "target",
              fmt::format("the voxel solver needs one target for every [[material]] ('{}' in "
                          "the first)",
                          c.material.target));
      s.check(m.target != "neural", "target",
              "several [[material]] entries need target = \"arap\" or \"analytic\"");
    }
    c.material_regions.push_back(m);
  }
}

void read_solver(const Section& s, SolverConfig& v) {
  v.method = s.choice("method", v.method, {"elastogen", "newton", "mpm"});
  v.relaxation = s.choice("relaxation", v.relaxation, {"jacobi", "chebyshev", "cg"});
  v.jacobi_omega = s.number("jacobi_omega", v.jacobi_omega);
  s.check(v.jacobi_omega > 0 && v.jacobi_omega <= 1, "jacobi_omega",
          fmt::format("must be in (0, 1], got {}", v.jacobi_omega));
  v.chebyshev_ratio = s.number("chebyshev_ratio", v.chebyshev_ratio);
  s.check(v.chebyshev_ratio >= 0 && v.chebyshev_ratio < 1, "chebyshev_ratio",
          fmt::format("must be in [0, 1), got {}", v.chebyshev_ratio));
  v.max_sweeps = s.integer("max_sweeps", v.max_sweeps);
  require_at_least(s, "max_sweeps", v.max_sweeps, 1);
  v.inner_tolerance = s.number("inner_tolerance", v.inner_tolerance);
  require_at_least(s, "inner_tolerance", v.inner_tolerance, 0);
  v.subspace_modes = s.integer("subspace_modes", v.subspace_modes);
  s.check(v.subspace_modes >= 0 && v.subspace_modes <= 64, "subspace_modes",
          fmt::format("must be in [0, 64], got {}", v.subspace_modes));
  v.max_outer = s.integer("max_outer", v.max_outer);
  require_at_least(s, "max_outer", v.max_outer, 1);
  v.outer_tolerance = s.number("outer_tolerance", v.outer_tolerance);
  require_positive(s, "outer_tolerance", v.outer_tolerance);
  v.accuracy_tolerance = s.number("accuracy_tolerance", v.accuracy_tolerance);
  require_positive(s, "accuracy_tolerance", v.accuracy_tolerance);
  v.max_extra_outer = s.integer("max_extra_outer", v.max_extra_outer);
  require_at_least(s, "max_extra_outer", v.max_extra_outer, 0);
  v.anderson_depth = s.integer("anderson_depth", v.anderson_depth);
  s.check(v.anderson_depth >= 0 && v.anderson_depth <= 16, "anderson_depth",
          fmt::format("must be in [0, 16], got {}", v.anderson_depth));
}

void read_mpm(const Section& s, MpmConfig& m) {
  m.has_box = s.has("lo") || s.has("hi");
  if (m.has_box) {
    m.lo = s.vec3("lo");
    m.hi = s.vec3("hi");
    require_box(s, m.lo, m.hi);
  }
  m.particles_per_axis = s.integer("particles_per_axis", m.particles_per_axis);
  s.check(m.particles_per_axis >= 1 && m.particles_per_axis <= 4, "particles_per_axis",
          fmt::format("must be in [1, 4], got {}", m.particles_per_axis));
  m.cfl = s.number("cfl", m.cfl);
  s.check(m.cfl > 0 && m.cfl <= 1, "cfl", fmt::format("must be in (0, 1], got {}", m.cfl));
  m.wave_cfl = s.number("wave_cfl", m.wave_cfl);
  s.check(m.wave_cfl > 0 && m.wave_cfl <= 1, "wave_cfl",
          fmt::format("must be in (0, 1], got {}", m.wave_cfl));
  m.substep = s.choice("substep", m.substep, {"adaptive", "fixed"});
  m.out_of_domain = s.choice("out_of_domain", m.out_of_domain, {"clamp", "remove"});
  m.boundary_layers = s.integer("boundary_layers", m.boundary_layers);
  s.check(m.boundary_layers >= 0 && m.boundary_layers <= 8, "boundary_layers",
          fmt::format("must be in [0, 8], got {}", m.boundary_layers));
  m.velocity = s.vec3("velocity", m.velocity);
  m.max_cells_per_substep = s.number("max_cells_per_substep", m.max_cells_per_substep);
  s.check(m.max_cells_per_substep > 0 && m.max_cells_per_substep <= 1, "max_cells_per_substep",
          fmt::format("must be in (0, 1], got {}", m.max_cells_per_substep));
  m.rpic_damping = s.number("rpic_damping", m.rpic_damping);
  s.check((m.rpic_damping >= 0 && m.rpic_damping <= 1) || m.rpic_damping == -1, "rpic_damping",
          fmt::format("must be in [0, 1], or -1 for PIC, got {}", m.rpic_damping));
  m.grid_velocity_scale = s.number("grid_velocity_scale", m.grid_velocity_scale);
  s.check(m.grid_velocity_scale > 0 && m.grid_velocity_scale <= 1, "grid_velocity_scale",
          fmt::format("must be in (0, 1], got {}", m.grid_velocity_scale));
}

std::vector<std::string> boundary_keys(const std::string& type) {
  if (type == "bounding_box") return {"type", "start", "end"};
  if (type == "cuboid")
    return {"type", "lo", "hi", "velocity", "motion", "reset_duration", "start", "end", "curve"};
  if (type == "particle_impulse") return {"type", "lo", "hi", "force", "start", "end", "curve"};
  if (type == "enforce_particle_translation")
    return {"type", "lo", "hi", "velocity", "start", "end", "curve"};
  if (type == "enforce_particle_velocity_rotation")
    return {"type",  "point", "normal", "radius", "half_height", "velocity", "angular_velocity",
            "start", "end",   "curve"};
  if (type == "surface_collider")
    return {"type", "point", "normal",    "surface", "friction",
            "lo",   "hi",    "cut_scale", "start",   "end"};
  return {"type", "normal", "layers", "start", "end"};  // release_particles_sequentially
}

Vec3d unit_normal(const Section& s, const Vec3d& n) {
  const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  s.check(len > 0, "normal", "must not be the zero vector");
  return {n[0] / len, n[1] / len, n[2] / len};
}

Curve curve_of(const Section& s, const std::vector<Curve>& curves);

BoundaryConfig read_boundary(const Section& s, const std::vector<Curve>& curves) {
  s.reject_unknown(key_names("boundary"));
  BoundaryConfig b;
  b.type = s.choice(
      "type", "",
      {"bounding_box", "cuboid", "particle_impulse", "enforce_particle_translation",
       "enforce_particle_velocity_rotation", "surface_collider", "release_particles_sequentially"});
  reject_foreign_keys(s, "boundary", b.type, boundary_keys(b.type));
  b.curve = curve_of(s, curves);
  read_window(s, b.start, b.end);
  if (b.type == "cuboid" || b.type == "particle_impulse" ||
      b.type == "enforce_particle_translation") {
    b.region = read_box(s);
  }
  if (b.type == "cuboid" || b.type == "enforce_particle_translation")
    b.velocity = s.vec3("velocity");
  if (b.type == "cuboid") {
    b.motion = s.choice("motion", b.motion, {"fixed", "moving"});
    b.reset_duration = s.number("reset_duration", b.reset_duration);
    require_at_least(s, "reset_duration", b.reset_duration, 0);
    if (b.reset_duration > 0)
      s.check(b.end < 1e299, "reset_duration", "needs an end: the reset starts at end");
  }
  if (b.type == "particle_impulse") b.force = s.vec3("force");
  if (b.type == "enforce_particle_velocity_rotation") {
    b.point = s.vec3("point");
    b.normal = unit_normal(s, s.vec3("normal"));
    b.radius = s.number("radius");
    require_positive(s, "radius", b.radius);
    b.half_height = s.number("half_height");
    require_positive(s, "half_height", b.half_height);
    b.velocity = s.vec3("velocity", b.velocity);
    b.angular_velocity = s.vec3("angular_velocity", b.angular_velocity);
  }
  if (b.type == "surface_collider") {
    b.point = s.vec3("point");
    b.normal = unit_normal(s, s.vec3("normal"));
    b.surface = s.choice("surface", b.surface, {"sticky", "slip", "separate", "cut"});
    b.friction = s.number("friction", b.friction);
    require_at_least(s, "friction", b.friction, 0);
    if (b.surface == "cut") {
      b.region = read_box(s);
      b.cut_scale = s.number("cut_scale", b.cut_scale);
      s.check(b.cut_scale >= 0 && b.cut_scale <= 1, "cut_scale",
              fmt::format("must be in [0, 1], got {}", b.cut_scale));
    } else {
      for (const char* key : {"lo", "hi", "cut_scale"})
        s.check(!s.has(key), key, "only applies to surface = \"cut\"");
    }
  }
  if (b.type == "release_particles_sequentially") {
    b.normal = unit_normal(s, s.vec3("normal", b.normal));
    b.layers = s.integer("layers", b.layers);
    require_at_least(s, "layers", b.layers, 1);
    s.check(b.end < 1e299, "end", "is required: layers are released evenly over [start, end]");
  }
  return b;
}

//! [[curve]]: a named piecewise-linear time factor (core/Curve.hpp).
Curve read_curve(const Section& s, const std::vector<Curve>& earlier) {
  s.reject_unknown(key_names("curve"));
  const std::string name = s.string("name");
  s.check(!name.empty(), "name", "must not be empty");
  for (const Curve& k : earlier)
    s.check(k.name() != name, "name", fmt::format("another [[curve]] is named '{}'", name));
  std::vector<double> t = s.numbers("time"), f = s.numbers("factor");
  s.check(f.size() == t.size(), "factor",
          fmt::format("needs one value per time ({}), got {}", t.size(), f.size()));
  for (std::size_t i = 1; i < t.size(); ++i)
    s.check(t[i] > t[i - 1], "time",
            fmt::format("must increase strictly, got {} after {}", t[i], t[i - 1]));
  return Curve(name, std::move(t), std::move(f));
}

//! The [[curve]] a load names with `curve = NAME`; without the key the constant 1.
Curve curve_of(const Section& s, const std::vector<Curve>& curves) {
  if (!s.has("curve")) return {};
  const std::string name = s.string("curve");
  std::vector<std::string> names;
  for (const Curve& k : curves) {
    if (k.name() == name) return k;
    names.push_back(k.name());
  }
  s.fail("curve", fmt::format("no [[curve]] is named '{}'{}", name,
                              names.empty() ? " (the deck has no [[curve]] table)"
                                            : deck::suggestion(name, names)));
}

FixedConfig read_fixed(const Section& s) {
  s.reject_unknown(key_names("fixed"));
  FixedConfig f;
  f.region = read_box(s);
  return f;
}

KinematicConfig read_kinematic(const Section& s, const std::vector<Curve>& curves) {
  s.reject_unknown(key_names("kinematic"));
  KinematicConfig k;
  k.region = read_box(s);
  k.center = s.vec3("center", k.center);
  k.velocity = s.vec3("velocity", k.velocity);
  k.angular_velocity = s.vec3("angular_velocity", k.angular_velocity);
  read_window(s, k.start, k.end);
  k.curve = curve_of(s, curves);
  return k;
}

ForceConfig read_force(const Section& s, const std::vector<Curve>& curves) {
  s.reject_unknown(key_names("force"));
  ForceConfig f;
  f.region = read_box(s);
  f.force = s.vec3("force");
  // start < 0: a pre-load (the run starts in static equilibrium under it).
  read_window(s, f.start, f.end, true);
  s.check(f.start >= 0 || f.end >= 0, "end",
          fmt::format("a pre-load (start < 0) is released at end >= 0, got {}", f.end));
  f.curve = curve_of(s, curves);
  s.check(f.start >= 0 || f.curve.name().empty(), "curve",
          "a pre-load (start < 0) takes no [[curve]]: it is constant until its end");
  return f;
}

PointMassConfig read_point_mass(const Section& s, std::string_view table) {
  s.reject_unknown(key_names(table));
  PointMassConfig p;
  p.region = read_box(s);
  p.mass = s.number("mass");
  require_positive(s, "mass", p.mass);
  return p;
}

ColliderConfig read_collider(const Section& s) {
  s.reject_unknown(key_names("collider"));
  ColliderConfig c;
  s.string("type");  // presence and type first, then the value
  c.type = s.choice("type", "", {"plane", "box"});
  reject_foreign_keys(s, "collider", c.type,
                      c.type == "plane"
                          ? std::vector<std::string>{"type", "point", "normal", "friction"}
                          : std::vector<std::string>{"type", "lo", "hi", "friction"});
  if (c.type == "plane") {
    c.point = s.vec3("point");
    c.normal = s.vec3("normal");
    const double n2 =
        c.normal[0] * c.normal[0] + c.normal[1] * c.normal[1] + c.normal[2] * c.normal[2];
    s.check(n2 > 0, "normal", fmt::format("must not be the zero vector, got {}", c.normal));
  } else {
    c.box = read_box(s);
  }
  c.friction = s.number("friction", c.friction);
  require_at_least(s, "friction", c.friction, 0);
  return c;
}

TractionConfig read_traction(const Section& s, const std::vector<Curve>& curves) {
  s.reject_unknown(key_names("traction"));
  TractionConfig t;
  t.region = read_box(s);
  if (!s.has("traction") && !s.has("pressure"))
    s.fail_table("needs 'traction' (vec3, Pa) or 'pressure' (Pa), or both");
  t.traction = s.vec3("traction", t.traction);
  t.pressure = s.number("pressure", t.pressure);
  read_window(s, t.start, t.end);
  t.curve = curve_of(s, curves);
  return t;
}

void read_output(const Section& s, OutputConfig& o) {
  o.dir = s.string("dir", o.dir);
  s.check(!o.dir.empty(), "dir", "must not be empty");
  o.frame_interval = s.number("frame_interval", o.frame_interval);
  require_at_least(s, "frame_interval", o.frame_interval, 0);
  o.checkpoint_every = s.integer("checkpoint_every", o.checkpoint_every);
  require_at_least(s, "checkpoint_every", o.checkpoint_every, 0);
  o.checkpoint_keep = s.integer("checkpoint_keep", o.checkpoint_keep);
  require_at_least(s, "checkpoint_keep", o.checkpoint_keep, 1);
  o.progress_interval = s.number("progress_interval", o.progress_interval);
  require_positive(s, "progress_interval", o.progress_interval);
  o.surface = s.choice("surface", o.surface, {"none", "ply", "obj"});
  o.surface_source = s.choice("surface_source", o.surface_source, {"auto", "mesh", "voxels"});
  o.particles = s.choice("particles", o.particles, {"none", "ply"});
  o.volumes = s.choice("volumes", o.volumes, {"none", "vdb"});
}

//! "auto", "orbit", or a 3DGS cameras.json "FILE[:INDEX]" resolved against the deck's folder.
//! Without the key: "orbit" when the table places the orbit (center or radius), else "auto".
std::string resolve_camera(Section& s, const fs::path& base_dir) {
  const std::string fallback = s.has("center") || s.has("radius") ? "orbit" : "auto";
  const std::string spec = s.string("camera", fallback);
  if (spec == "orbit" || spec == "auto") return spec;
  std::string file = spec, index;
  const auto colon = spec.rfind(':');
  if (colon != std::string::npos && colon + 1 < spec.size() &&
      std::all_of(spec.begin() + static_cast<long>(colon) + 1, spec.end(),
                  [](unsigned char ch) { return std::isdigit(ch) != 0; })) {
    file = spec.substr(0, colon);
    index = spec.substr(colon);
  }
  s.check(!file.empty(), "camera", "must be \"auto\", \"orbit\" or a cameras.json file[:index]");
  return resolve_existing(s, "camera", file, base_dir, "cameras file not found", index);
}

//! [render]; a deck with splat geometry renders even without the table (camera "auto").
void read_render(Section& s, const fs::path& base_dir, const Config& c, RenderConfig& r) {
  const bool splats = std::any_of(c.geometry.begin(), c.geometry.end(),
                                  [](const GeometryConfig& g) { return g.type == "splats"; });
  if (!s.present() && !splats) return;
  r.enabled = true;
  r.camera = resolve_camera(s, base_dir);
  if (r.camera == "auto")
    for (const char* key : {"center", "radius"})
      if (s.has(key))
        s.fail(key, "only applies to camera = \"orbit\" (\"auto\" frames the object)");
  const bool orbit = r.camera == "orbit" || r.camera == "auto";
  for (const char* key : {"center", "up", "azimuth", "elevation", "radius", "d_azimuth",
                          "d_elevation", "d_radius", "fov_y", "width", "height"})
    if (!orbit && s.has(key))
      s.fail(key, "only applies to the orbit cameras (a cameras.json entry sets its own view)");
  r.center = s.vec3("center", r.center);
  r.up = s.vec3("up", r.up);
  require_nonzero_vector(s, "up", r.up);
  r.azimuth = s.number("azimuth", r.azimuth);
  r.elevation = s.number("elevation", r.elevation);
  s.check(r.elevation > -90 && r.elevation < 90, "elevation",
          fmt::format("must be in (-90, 90) degrees, got {}", r.elevation));
  r.radius = s.number("radius", r.radius);
  require_positive(s, "radius", r.radius);
  r.d_azimuth = s.number("d_azimuth", r.d_azimuth);
  r.d_elevation = s.number("d_elevation", r.d_elevation);
  r.d_radius = s.number("d_radius", r.d_radius);
  r.fov_y = s.number("fov_y", r.fov_y);
  s.check(r.fov_y > 0 && r.fov_y < 180, "fov_y",
          fmt::format("must be in (0, 180) degrees, got {}", r.fov_y));
  r.width = s.integer("width", r.width);
  require_at_least(s, "width", r.width, 1);
  r.height = s.integer("height", r.height);
  require_at_least(s, "height", r.height, 1);
  s.check(static_cast<long long>(r.width) * r.height <= 16384LL * 16384LL, "width",
          fmt::format("image of {} x {} pixels is too large", r.width, r.height));
  r.background = s.vec3("background", r.background);
  require_unit_colour(s, "background", r.background);
  r.kinematics = s.choice("kinematics", r.kinematics,
                          {"full", "fixed_covariance", "rigid_covariance", "fixed_harmonics"});
  r.covariance_update =
      s.choice("covariance_update", r.covariance_update, {"deformation_gradient", "rate"});
  r.splat_spacing = s.number("splat_spacing", r.splat_spacing);
  require_at_least(s, "splat_spacing", r.splat_spacing, 0.0);
  r.mp4 = s.choice("video", "none", {"none", "mp4"}) == "mp4";
  r.layout = s.choice("layout", r.layout, {"gen4d", "physgaussian"});
  r.fps = s.number("fps", r.fps);
  s.check(!s.has("fps") || (r.fps > 0 && r.fps <= 1000), "fps",
          fmt::format("must be in (0, 1000] frames per second, got {}", r.fps));
  if (s.has("scenery")) {
    const std::string file = s.string("scenery");
    s.check(!file.empty(), "scenery", "must name a 3DGS PLY file");
    r.scenery = resolve_existing(s, "scenery", file, base_dir);
  }
}

//! A mesh surface needs mesh geometry: every [[geometry]] part must be a mesh.
void check_surface_source(const Section& s, const Config& c) {
  if (c.output.surface_source != "mesh") return;
  for (std::size_t i = 0; i < c.geometry.size(); ++i)
    s.check(c.geometry[i].type == "mesh", "surface_source",
            fmt::format("\"mesh\" needs every [[geometry]] part to be a mesh, but geometry.{} is a "
                        "{} (use \"auto\" or \"voxels\")",
                        i, c.geometry[i].type));
}

// The final deck text. Structure and numbers are written here rather than by toml++'s
// formatter because the packaged toml++ prints every float with 17 significant digits
// (0.05 -> 0.050000000000000003), which makes stored decks hard to read; fmt's shortest
// round-trip form re-parses to the same doubles. Strings keep toml++'s quoting and escaping.
std::string number_text(const toml::node& node, deck::Kind kind) {
  if (const auto* i = node.as_integer()) return std::to_string(i->get());
  // Validation accepted only integral values for integer keys; write them as integers.
  if (kind == deck::Kind::Integer)
    return std::to_string(static_cast<long long>(*node.value<double>()));
  std::string text = fmt::format("{}", *node.value<double>());
  // Keep floats floats: "1000000" would re-parse as an integer.
  if (text.find_first_of(".eEn") == std::string::npos) text += ".0";
  return text;
}

std::string value_text(const toml::node& node, deck::Kind kind) {
  if (const auto* s = node.as_string()) {
    std::ostringstream os;
    os << *s;
    return os.str();
  }
  if (const auto* arr = node.as_array()) {
    std::string text = "[";
    for (std::size_t i = 0; i < arr->size(); ++i)
      text += (i ? ", " : "") + number_text((*arr)[i], deck::Kind::Number);
    return text + "]";
  }
  return number_text(node, kind);
}

void write_table(std::ostringstream& os, const std::string& header, const toml::table& table,
                 const deck::TableSpec& spec) {
  if (os.tellp() > 0) os << '\n';
  os << header << '\n';
  for (const auto& key : spec.keys)
    if (const toml::node* node = table.get(key.name))
      os << key.name << " = " << value_text(*node, key.kind) << '\n';
}

//! Writes a validated root (only schema keys, numbers, 3-vectors, strings) in schema order.
std::string write_deck_text(const toml::table& root) {
  std::ostringstream os;
  for (const auto& spec : deck::schema()) {
    const toml::node* node = root.get(spec.name);
    if (!node) continue;
    const std::string name(spec.name);
    if (const auto* table = node->as_table()) write_table(os, "[" + name + "]", *table, spec);
    if (const auto* arr = node->as_array())
      for (const auto& element : *arr)
        write_table(os, "[[" + name + "]]", *element.as_table(), spec);
  }
  return os.str();
}

//! Config::where: FILE:LINE (or the --set that gave it) of every table and key of the deck.
void record_where(const toml::table& root, const Locator& loc, Config& c) {
  // A table that only --set made has no line: point at the first override inside it.
  const auto at = [&](const toml::node& node, const std::string& path) {
    if (node.source().begin.line == 0)
      for (const auto& [key, text] : loc.origins())
        if (key.rfind(path + ".", 0) == 0) return "--set " + text;
    return loc.at(&node, path);
  };
  const auto note = [&](const toml::table& t, const std::string& name, const std::string& path) {
    c.where.emplace(name, at(t, path));
    for (auto&& [key, value] : t) {
      const std::string k(key.str());
      c.where.emplace(name + "." + k, at(value, path + "." + k));
    }
  };
  for (auto&& [key, value] : root) {
    const std::string name(key.str());
    if (const auto* t = value.as_table()) note(*t, name, name);
    if (const auto* arr = value.as_array())
      for (std::size_t i = 0; i < arr->size(); ++i)
        if (const auto* t = arr->get_as<toml::table>(i))
          note(*t, name, fmt::format("{}.{}", name, i));
  }
}

//! A [[curve]] no load names is a mistake (the load it was meant for runs at full value).
void reject_unreferenced_curves(const Config& c, const std::vector<Section>& sections) {
  for (std::size_t i = 0; i < c.curves.size(); ++i) {
    const std::string& name = c.curves[i].name();
    bool used = false;
    for (const auto& k : c.kinematic) used = used || k.curve.name() == name;
    for (const auto& f : c.forces) used = used || f.curve.name() == name;
    for (const auto& t : c.tractions) used = used || t.curve.name() == name;
    for (const auto& b : c.boundaries) used = used || b.curve.name() == name;
    sections[i].check(used, "name",
                      fmt::format("no load names curve '{}' (give a [[force]], [[traction]], "
                                  "[[kinematic]] or [[boundary]] the key curve = \"{}\")",
                                  name, name));
  }
}

toml::table parse_toml(const std::string& text, const std::string& source_name) {
  try {
    return toml::parse(std::string_view(text), std::string_view(source_name));
  } catch (const toml::parse_error& e) {
    throw InputError(fmt::format("{}:{}:{}: TOML syntax error: {}", source_name,
                                 e.source().begin.line, e.source().begin.column, e.description()));
  }
}

}  // namespace

Config parse_deck(const std::string& text, const std::string& source_name,
                  const std::string& base_dir, const std::vector<std::string>& overrides) {
  toml::table root = parse_toml(text, source_name);
  const Locator loc(source_name, deck::apply_overrides(root, overrides));
  reject_unknown_tables(root, loc);

  Config c;
  read_simulation(table_section(root, "simulation", loc), c);
  read_domain(table_section(root, "domain", loc), c);
  read_geometries(root, loc, fs::path(base_dir.empty() ? "." : base_dir), c);
  read_solver(table_section(root, "solver", loc), c.solver);
  read_materials(root, loc, fs::path(base_dir.empty() ? "." : base_dir), c);
  record_where(root, loc, c);
  // Tables a solver does not read are refused by check_deck_use below, after all are valid.
  const bool mpm = c.solver.method == "mpm";
  if (mpm && !c.cubic_cells())
    table_section(root, "domain", loc)
        .fail("voxel_size",
              fmt::format("the MPM grid takes cubic cells (one number), got {}", c.spacing));
  if (mpm) read_mpm(table_section(root, "mpm", loc), c.mpm);
  const std::vector<Section> curves = array_sections(root, "curve", loc);
  for (const Section& s : curves) c.curves.push_back(read_curve(s, c.curves));
  for (const Section& s : array_sections(root, "boundary", loc))
    if (mpm) c.boundaries.push_back(read_boundary(s, c.curves));
  for (const Section& s : array_sections(root, "fixed", loc)) c.fixed.push_back(read_fixed(s));
  for (const Section& s : array_sections(root, "kinematic", loc))
    c.kinematic.push_back(read_kinematic(s, c.curves));
  for (const Section& s : array_sections(root, "force", loc))
    c.forces.push_back(read_force(s, c.curves));
  for (const char* table : {"point_mass", "attached_mass"})
    for (const Section& s : array_sections(root, table, loc)) {
      c.point_masses.push_back(read_point_mass(s, table));
      c.point_masses.back().where = s.where("mass");
    }
  for (const Section& s : array_sections(root, "collider", loc)) {
    c.colliders.push_back(read_collider(s));
    // The MPM's box obstacle is a still cuboid: the grid nodes inside it stop (no slip).
    if (mpm && c.colliders.back().type == "box")
      s.check(!s.has("friction"), "friction",
              "an MPM box collider holds what touches it (no slip); friction applies to plane "
              "colliders");
  }
  for (const Section& s : array_sections(root, "traction", loc))
    c.tractions.push_back(read_traction(s, c.curves));
  const Section output = table_section(root, "output", loc);
  read_output(output, c.output);
  check_surface_source(output, c);
  {
    Section render = table_section(root, "render", loc);
    read_render(render, fs::path(base_dir.empty() ? "." : base_dir), c, c.render);
  }

  c.text = write_deck_text(root);
  c.source = source_name;
  check_deck_use(c, run_user(c));
  reject_unreferenced_curves(c, curves);
  return c;
}

Config load_deck(const std::string& path, const std::vector<std::string>& overrides) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec))
    throw InputError(fmt::format("{}: deck file not found", path));
  const std::string text = read_whole_file(path, "deck");
  const fs::path parent = fs::path(path).parent_path();
  return parse_deck(text, path, parent.empty() ? "." : parent.string(), overrides);
}

}  // namespace gen4d
