#include "core/Deck.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/DeckReader.hpp"
#include "core/Error.hpp"

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
  c.voxel_size = s.number("voxel_size");
  require_positive(s, "voxel_size", c.voxel_size);
  c.padding = s.integer("padding", c.padding);
  require_at_least(s, "padding", c.padding, 0);
}

std::vector<std::string> geometry_keys(const std::string& type) {
  if (type == "box") return {"type", "lo", "hi"};
  if (type == "sphere") return {"type", "center", "radius"};
  if (type == "capsule") return {"type", "a", "b", "radius"};
  if (type == "mesh") return {"type", "file", "scale", "translate"};
  return {"type", "file", "grid", "scale", "translate"};  // vdb
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
  const fs::path path = fs::absolute(base_dir / fs::path(file)).lexically_normal();
  std::error_code ec;
  s.check(fs::is_regular_file(path, ec), "file", fmt::format("file not found: {}", path.string()));
  s.replace("file", path.string());
  return path.string();
}

GeometryConfig read_geometry(Section& s, const fs::path& base_dir) {
  GeometryConfig g;
  s.string("type");  // presence and type first, then the value
  g.type = s.choice("type", "", {"box", "sphere", "capsule", "mesh", "vdb"});
  reject_foreign_geometry_keys(s, g.type);
  if (g.type == "box") {
    g.lo = s.vec3("lo");
    g.hi = s.vec3("hi");
    require_box(s, g.lo, g.hi);
  } else if (g.type == "sphere") {
    g.center = s.vec3("center");
    g.radius = s.number("radius");
    require_positive(s, "radius", g.radius);
  } else if (g.type == "capsule") {
    g.a = s.vec3("a");
    g.b = s.vec3("b");
    g.radius = s.number("radius");
    require_positive(s, "radius", g.radius);
  } else {
    g.file = resolve_file(s, base_dir, g.type == "mesh");
    if (g.type == "vdb") g.grid = s.string("grid", g.grid);
    g.scale = s.number("scale", g.scale);
    require_positive(s, "scale", g.scale);
    g.translate = s.vec3("translate", g.translate);
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
  }
}

void read_material(Section& s, MaterialConfig& m, const fs::path& base_dir) {
  m.model = s.choice("model", m.model, {"corotated", "neo_hookean", "stvk", "linear"});
  m.target = s.choice("target", m.target, {"analytic", "arap", "neural"});
  if (m.target == "neural") {
    s.check(m.model != "linear", "model",
            "target = \"neural\" needs a hyperelastic law (corotated, neo_hookean or stvk)");
    if (s.has("neural_weights")) {
      const std::string file = s.string("neural_weights");
      s.check(!file.empty(), "neural_weights", "must not be empty (leave it out to generate)");
      const fs::path path = fs::absolute(base_dir / fs::path(file)).lexically_normal();
      std::error_code ec;
      s.check(fs::is_regular_file(path, ec), "neural_weights",
              fmt::format("file not found: {}", path.string()));
      s.replace("neural_weights", path.string());
      m.neural_weights = path.string();
    }
  } else {
    s.check(!s.has("neural_weights"), "neural_weights", "only applies to target = \"neural\"");
  }
  m.youngs_modulus = s.number("youngs_modulus");
  require_positive(s, "youngs_modulus", m.youngs_modulus);
  m.poisson_ratio = s.number("poisson_ratio");
  s.check(m.poisson_ratio > -1 && m.poisson_ratio < 0.5, "poisson_ratio",
          fmt::format("must be in (-1, 0.5), got {}", m.poisson_ratio));
  m.density = s.number("density");
  require_positive(s, "density", m.density);
}

void read_solver(const Section& s, SolverConfig& v) {
  v.method = s.choice("method", v.method, {"elastogen", "newton"});
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

FixedConfig read_fixed(const Section& s) {
  s.reject_unknown(key_names("fixed"));
  FixedConfig f;
  f.region.lo = s.vec3("lo");
  f.region.hi = s.vec3("hi");
  require_box(s, f.region.lo, f.region.hi);
  return f;
}

KinematicConfig read_kinematic(const Section& s) {
  s.reject_unknown(key_names("kinematic"));
  KinematicConfig k;
  k.region.lo = s.vec3("lo");
  k.region.hi = s.vec3("hi");
  require_box(s, k.region.lo, k.region.hi);
  k.center = s.vec3("center", k.center);
  k.velocity = s.vec3("velocity", k.velocity);
  k.angular_velocity = s.vec3("angular_velocity", k.angular_velocity);
  k.start = s.number("start", k.start);
  require_at_least(s, "start", k.start, 0);
  k.end = s.number("end", k.end);
  s.check(k.end > k.start, "end", fmt::format("must be > start ({}), got {}", k.start, k.end));
  return k;
}

ForceConfig read_force(const Section& s) {
  s.reject_unknown(key_names("force"));
  ForceConfig f;
  f.region.lo = s.vec3("lo");
  f.region.hi = s.vec3("hi");
  require_box(s, f.region.lo, f.region.hi);
  f.force = s.vec3("force");
  f.start = s.number("start", f.start);
  require_at_least(s, "start", f.start, 0);
  f.end = s.number("end", f.end);
  s.check(f.end > f.start, "end", fmt::format("must be > start ({}), got {}", f.start, f.end));
  return f;
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
    c.box.lo = s.vec3("lo");
    c.box.hi = s.vec3("hi");
    require_box(s, c.box.lo, c.box.hi);
  }
  c.friction = s.number("friction", c.friction);
  require_at_least(s, "friction", c.friction, 0);
  return c;
}

TractionConfig read_traction(const Section& s) {
  s.reject_unknown(key_names("traction"));
  TractionConfig t;
  t.region.lo = s.vec3("lo");
  t.region.hi = s.vec3("hi");
  require_box(s, t.region.lo, t.region.hi);
  if (!s.has("traction") && !s.has("pressure"))
    s.fail_table("needs 'traction' (vec3, Pa) or 'pressure' (Pa), or both");
  t.traction = s.vec3("traction", t.traction);
  t.pressure = s.number("pressure", t.pressure);
  t.start = s.number("start", t.start);
  require_at_least(s, "start", t.start, 0);
  t.end = s.number("end", t.end);
  s.check(t.end > t.start, "end", fmt::format("must be > start ({}), got {}", t.start, t.end));
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
  {
    Section material = table_section(root, "material", loc);
    read_material(material, c.material, fs::path(base_dir.empty() ? "." : base_dir));
  }
  read_solver(table_section(root, "solver", loc), c.solver);
  for (const Section& s : array_sections(root, "fixed", loc)) c.fixed.push_back(read_fixed(s));
  for (const Section& s : array_sections(root, "kinematic", loc))
    c.kinematic.push_back(read_kinematic(s));
  for (const Section& s : array_sections(root, "force", loc)) c.forces.push_back(read_force(s));
  for (const Section& s : array_sections(root, "collider", loc))
    c.colliders.push_back(read_collider(s));
  for (const Section& s : array_sections(root, "traction", loc))
    c.tractions.push_back(read_traction(s));
  const Section output = table_section(root, "output", loc);
  read_output(output, c.output);
  check_surface_source(output, c);

  c.text = write_deck_text(root);
  c.source = source_name;
  return c;
}

Config load_deck(const std::string& path, const std::vector<std::string>& overrides) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec))
    throw InputError(fmt::format("{}: deck file not found", path));
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(fmt::format("{}: cannot open the deck", path));
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw InputError(fmt::format("{}: cannot read the deck", path));
  const fs::path parent = fs::path(path).parent_path();
  return parse_deck(text.str(), path, parent.empty() ? "." : parent.string(), overrides);
}

}  // namespace gen4d
