#include "core/DeckReader.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>

#include "core/Error.hpp"

namespace gen4d::deck {

const KeySpec* TableSpec::find(std::string_view key) const {
  for (const auto& k : keys)
    if (k.name == key) return &k;
  return nullptr;
}

namespace {

//! The keys of one table from whitespace-separated "name:kind" words (kind: s string, n number,
//! i integer, v vec3, l list of numbers). `spec` is a literal, so the names stay valid.
std::vector<KeySpec> keys(std::string_view spec) {
  std::vector<KeySpec> out;
  while (!spec.empty()) {
    const std::size_t start = spec.find_first_not_of(' ');
    if (start == std::string_view::npos) break;
    spec.remove_prefix(start);
    const std::size_t end = std::min(spec.find(' '), spec.size());
    const std::string_view word = spec.substr(0, end);
    const std::size_t colon = word.find(':');
    if (colon == std::string_view::npos || colon + 2 != word.size())
      throw RuntimeError(fmt::format("deck schema: malformed key '{}'", word));
    // The letters in the order of Kind's enumerators.
    const std::size_t kind = std::string_view("snivlx").find(word.back());
    if (kind == std::string_view::npos)
      throw RuntimeError(fmt::format("deck schema: unknown kind in '{}'", word));
    out.push_back({word.substr(0, colon), static_cast<Kind>(kind)});
    spec.remove_prefix(end);
  }
  return out;
}

}  // namespace

const std::vector<TableSpec>& schema() {
  static const std::vector<TableSpec> tables = {
      {"simulation", false, keys("name:s dt:n end_time:n gravity:v")},
      {"domain", false, keys("voxel_size:x padding:i")},
      {"geometry", true,
       keys("type:s name:s lo:v hi:v center:v a:v b:v radius:n file:s grid:s scale:n translate:v "
            "rotate_axis:v rotate_degrees:n opacity_threshold:n fill_cells:i color:v")},
      {"material", false,
       keys("model:s target:s youngs_modulus:n poisson_ratio:n density:n neural_weights:s "
            // MPM models (solver.method = "mpm"); which model takes which key: inputs/README.md.
            "friction_angle:n cohesion:n yield_stress:n hardening:n jc_A:n jc_B:n jc_n:n jc_C:n "
            "jc_m:n reference_strain_rate:n room_temperature:n melt_temperature:n "
            "initial_temperature:n specific_heat:n taylor_quinney:n consistency:n flow_index:n "
            "fracture_strain:n failure_strain:n critical_compression:n critical_stretch:n "
            "hardening_coefficient:n "
            // Binding of a [[material]] entry after the first.
            "geometry:s lo:v hi:v"),
       true},
      {"solver", false,
       keys("method:s relaxation:s jacobi_omega:n chebyshev_ratio:n max_sweeps:i "
            "inner_tolerance:n subspace_modes:i max_outer:i outer_tolerance:n "
            "accuracy_tolerance:n max_extra_outer:i anderson_depth:i")},
      {"mpm", false,
       keys("lo:v hi:v particles_per_axis:i cfl:n wave_cfl:n substep:s out_of_domain:s "
            "boundary_layers:i velocity:v max_cells_per_substep:n rpic_damping:n "
            "grid_velocity_scale:n")},
      {"boundary", true,
       keys("type:s curve:s lo:v hi:v point:v normal:v velocity:v angular_velocity:v force:v "
            "radius:n half_height:n surface:s friction:n cut_scale:n motion:s reset_duration:n "
            "layers:i start:n end:n")},
      {"fixed", true, keys("lo:v hi:v")},
      {"kinematic", true,
       keys("lo:v hi:v center:v velocity:v angular_velocity:v start:n end:n curve:s")},
      {"force", true, keys("lo:v hi:v force:v start:n end:n curve:s")},
      {"point_mass", true, keys("lo:v hi:v mass:n")},
      {"attached_mass", true, keys("lo:v hi:v mass:n")},
      {"collider", true, keys("type:s point:v normal:v lo:v hi:v friction:n")},
      {"traction", true, keys("lo:v hi:v traction:v pressure:n start:n end:n curve:s")},
      {"curve", true, keys("name:s time:l factor:l")},
      {"output", false,
       keys("dir:s frame_interval:n checkpoint_every:i checkpoint_keep:i progress_interval:n "
            "surface:s surface_source:s particles:s volumes:s")},
      {"render", false,
       keys("camera:s center:v up:v azimuth:n elevation:n radius:n d_azimuth:n d_elevation:n "
            "d_radius:n fov_y:n width:i height:i background:v kinematics:s covariance_update:s "
            "splat_spacing:n video:s layout:s fps:n scenery:s")},
  };
  return tables;
}

const TableSpec* find_table(std::string_view name) {
  for (const auto& t : schema())
    if (t.name == name) return &t;
  return nullptr;
}

namespace {

// Optimal string alignment distance: a swapped pair of letters counts as one typo.
std::size_t edit_distance(std::string_view a, std::string_view b) {
  const std::size_t n = a.size(), m = b.size();
  std::vector<std::vector<std::size_t>> d(n + 1, std::vector<std::size_t>(m + 1));
  for (std::size_t i = 0; i <= n; ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= m; ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= n; ++i) {
    for (std::size_t j = 1; j <= m; ++j) {
      const std::size_t cost = std::tolower(a[i - 1]) == std::tolower(b[j - 1]) ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  }
  return d[n][m];
}

std::string format_vec(const toml::array& arr) {
  std::string out = "[";
  for (std::size_t i = 0; i < arr.size(); ++i) {
    if (i) out += ", ";
    const auto& e = arr[i];
    if (auto v = e.value<double>())
      out += fmt::format("{}", *v);
    else
      out += type_name(e);
  }
  return out + "]";
}

}  // namespace

std::string suggestion(std::string_view word, const std::vector<std::string>& candidates,
                       std::string_view prefix) {
  const std::string* best = nullptr;
  std::size_t best_distance = 3;
  for (const auto& c : candidates) {
    const std::size_t dist = edit_distance(word, c);
    // A distance as long as the word itself means nothing of it was kept.
    if (dist < best_distance && dist < std::max(word.size(), c.size())) {
      best = &c;
      best_distance = dist;
    }
  }
  // Abbreviations ("youngs" for "youngs_modulus") are far in edit distance but unambiguous.
  if (!best && word.size() >= 4)
    for (const auto& c : candidates)
      if (c.find(word) != std::string::npos) {
        best = &c;
        break;
      }
  return best ? fmt::format(" (did you mean '{}{}'?)", prefix, *best) : std::string();
}

std::string type_name(const toml::node& node) {
  switch (node.type()) {
    case toml::node_type::string:
      return "string";
    case toml::node_type::integer:
      return "integer";
    case toml::node_type::floating_point:
      return "float";
    case toml::node_type::boolean:
      return "boolean";
    case toml::node_type::array:
      return "array";
    case toml::node_type::table:
      return "table";
    case toml::node_type::date:
      return "date";
    case toml::node_type::time:
      return "time";
    case toml::node_type::date_time:
      return "date-time";
    default:
      return "nothing";
  }
}

std::string Locator::at(const toml::node* node, const std::string& path) const {
  if (auto it = origins_.find(path); it != origins_.end()) return "--set " + it->second;
  if (node && node->source().begin.line > 0)
    return fmt::format("{}:{}", source_, node->source().begin.line);
  return source_;
}

void Locator::fail(const toml::node* node, const std::string& path,
                   const std::string& message) const {
  throw InputError(fmt::format("{}: key '{}': {}", at(node, path), path, message));
}

std::string Section::where(std::string_view key) const {
  return loc_.at(node(key), key_path(key));
}

const toml::node* Section::node(std::string_view key) const {
  return table_ ? table_->get(key) : nullptr;
}

std::string Section::key_path(std::string_view key) const {
  return path_.empty() ? std::string(key) : fmt::format("{}.{}", path_, key);
}

void Section::reject_unknown(const std::vector<std::string>& allowed) const {
  if (!table_) return;
  const toml::node* first = nullptr;
  std::string first_key;
  for (auto&& [key, value] : *table_) {
    if (std::find(allowed.begin(), allowed.end(), key.str()) != allowed.end()) continue;
    // toml::table is ordered by name; report the key the user meets first in the file.
    if (!first || value.source().begin.line < first->source().begin.line) {
      first = &value;
      first_key = std::string(key.str());
    }
  }
  if (!first) return;
  const std::string path = key_path(first_key);
  throw InputError(fmt::format("{}: unknown key '{}'{}", loc_.at(first, path), path,
                               suggestion(first_key, allowed, path_.empty() ? "" : path_ + ".")));
}

void Section::fail(std::string_view key, const std::string& message) const {
  loc_.fail(node(key), key_path(key), message);
}

void Section::fail_table(const std::string& message) const {
  loc_.fail(header_, path_, message);
}

const toml::node& Section::required(std::string_view key) const {
  if (const toml::node* n = node(key)) return *n;
  const std::string path = key_path(key);
  throw InputError(fmt::format("{}: missing required key '{}'", loc_.at(header_, path_), path));
}

double Section::number(std::string_view key) const {
  const toml::node& n = required(key);
  if (!n.is_integer() && !n.is_floating_point())
    fail(key, "expected a number, got " + type_name(n));
  const double v = *n.value<double>();
  check(std::isfinite(v), key, fmt::format("must be finite, got {}", v));
  return v;
}

double Section::number(std::string_view key, double fallback) const {
  return has(key) ? number(key) : fallback;
}

int Section::integer(std::string_view key) const {
  const toml::node& n = required(key);
  constexpr double lo = std::numeric_limits<int>::min(), hi = std::numeric_limits<int>::max();
  if (const auto* i = n.as_integer()) {
    check(i->get() >= lo && i->get() <= hi, key, fmt::format("out of range, got {}", i->get()));
    return static_cast<int>(i->get());
  }
  if (const auto* f = n.as_floating_point()) {
    const double v = f->get();
    check(std::isfinite(v) && v == std::floor(v) && v >= lo && v <= hi, key,
          fmt::format("expected an integer, got {}", v));
    return static_cast<int>(v);
  }
  fail(key, "expected an integer, got " + type_name(n));
}

int Section::integer(std::string_view key, int fallback) const {
  return has(key) ? integer(key) : fallback;
}

std::string Section::string(std::string_view key) const {
  const toml::node& n = required(key);
  if (!n.is_string()) fail(key, "expected a string, got " + type_name(n));
  return *n.value<std::string>();
}

std::string Section::string(std::string_view key, const std::string& fallback) const {
  return has(key) ? string(key) : fallback;
}

Vec3d Section::vec3(std::string_view key) const {
  const toml::node& n = required(key);
  const toml::array* arr = n.as_array();
  if (!arr) fail(key, "expected an array of 3 numbers, got " + type_name(n));
  if (arr->size() != 3)
    fail(key, fmt::format("expected an array of 3 numbers, got {} element{}", arr->size(),
                          arr->size() == 1 ? "" : "s"));
  Vec3d v{};
  for (std::size_t d = 0; d < 3; ++d) {
    const toml::node& e = (*arr)[d];
    if (!e.is_integer() && !e.is_floating_point())
      fail(key, fmt::format("element {} must be a number, got {}", d, type_name(e)));
    v[d] = *e.value<double>();
    check(std::isfinite(v[d]), key, fmt::format("must be finite, got {}", format_vec(*arr)));
  }
  return v;
}

Vec3d Section::vec3(std::string_view key, const Vec3d& fallback) const {
  return has(key) ? vec3(key) : fallback;
}

std::vector<double> Section::numbers(std::string_view key) const {
  const toml::node& n = required(key);
  const toml::array* arr = n.as_array();
  if (!arr) fail(key, "expected an array of numbers, got " + type_name(n));
  if (arr->empty()) fail(key, "expected an array of numbers, got an empty array");
  std::vector<double> out;
  for (std::size_t i = 0; i < arr->size(); ++i) {
    const toml::node& e = (*arr)[i];
    if (!e.is_integer() && !e.is_floating_point())
      fail(key, fmt::format("element {} must be a number, got {}", i, type_name(e)));
    out.push_back(*e.value<double>());
    check(std::isfinite(out.back()), key, fmt::format("must be finite, got {}", format_vec(*arr)));
  }
  return out;
}

std::string Section::choice(std::string_view key, const std::string& fallback,
                            const std::vector<std::string>& choices) const {
  const std::string v = string(key, fallback);
  if (std::find(choices.begin(), choices.end(), v) != choices.end()) return v;
  std::string list;
  for (const auto& c : choices) list += (list.empty() ? "" : ", ") + c;
  fail(key, fmt::format("must be one of {}, got '{}'{}", list, v, suggestion(v, choices)));
}

void Section::replace(std::string_view key, const std::string& value) {
  if (table_) table_->insert_or_assign(key, value);
}

}  // namespace gen4d::deck
