// --set key=value overrides: dotted key paths into the schema, values parsed as TOML.
#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <optional>

#include "core/DeckReader.hpp"
#include "core/Error.hpp"

namespace gen4d::deck {
namespace {

std::string trim(std::string_view s) {
  std::size_t b = 0, e = s.size();
  while (b < e && std::isspace(static_cast<unsigned char>(s[b]))) ++b;
  while (e > b && std::isspace(static_cast<unsigned char>(s[e - 1]))) --e;
  return std::string(s.substr(b, e - b));
}

bool is_control(char c) {
  return static_cast<unsigned char>(c) < 0x20 && c != '\t';
}

//! The override as it can be echoed on one message line.
std::string printable(const std::string& text) {
  std::string out;
  for (char c : text)
    out +=
        is_control(c) ? fmt::format("\\x{:02x}", static_cast<unsigned char>(c)) : std::string(1, c);
  return out;
}

std::vector<std::string> split_dots(const std::string& key) {
  std::vector<std::string> parts;
  std::size_t start = 0;
  while (true) {
    const std::size_t dot = key.find('.', start);
    parts.push_back(key.substr(start, dot == std::string::npos ? dot : dot - start));
    if (dot == std::string::npos) return parts;
    start = dot + 1;
  }
}

//! The value as a one-entry TOML document, or nothing if it is not exactly one TOML value.
std::optional<toml::table> parse_value(const std::string& value) {
  try {
    toml::table doc = toml::parse(std::string_view("v = " + value));
    if (doc.size() == 1 && doc.contains("v")) return doc;
  } catch (const toml::parse_error&) {
  }
  return std::nullopt;
}

//! Number keys also take C notation that TOML lacks (".5", "1.", "1E5").
std::optional<double> parse_c_number(const std::string& value) {
  if (value.empty()) return std::nullopt;
  char* end = nullptr;
  const double v = std::strtod(value.c_str(), &end);
  if (end != value.c_str() + value.size()) return std::nullopt;
  return v;
}

//! Builds the node for `value` as `kind` wants it, or throws naming what was expected.
toml::table typed_value(const std::string& value, Kind kind, const std::string& where) {
  std::optional<toml::table> doc = parse_value(value);
  const toml::node* node = doc ? doc->get("v") : nullptr;
  toml::table out;
  switch (kind) {
    case Kind::String:
      // Unquoted strings (relaxation=cg, dir=out/run1) are taken as written.
      if (node && node->is_string()) return *doc;
      out.insert("v", value);
      return out;
    case Kind::Number:
      if (node && (node->is_integer() || node->is_floating_point())) return *doc;
      if (!node) {
        if (auto v = parse_c_number(value)) {
          out.insert("v", *v);
          return out;
        }
        throw InputError(fmt::format("{}: expected a number, got '{}'", where, value));
      }
      throw InputError(fmt::format("{}: expected a number, got {}", where, type_name(*node)));
    case Kind::Integer:
      // Integral checks (2.0 is fine, 2.5 is not) happen when the deck is read.
      if (node && (node->is_integer() || node->is_floating_point())) return *doc;
      throw InputError(fmt::format("{}: expected an integer, got {}", where,
                                   node ? type_name(*node) : "'" + value + "'"));
    case Kind::Vec3:
      if (node && node->is_array()) return *doc;
      throw InputError(fmt::format("{}: expected an array of 3 numbers like [0, 0, -9.81], got {}",
                                   where, node ? type_name(*node) : "'" + value + "'"));
    case Kind::NumberOrVec3:
      if (node && (node->is_array() || node->is_integer() || node->is_floating_point()))
        return *doc;
      if (!node)
        if (auto v = parse_c_number(value)) {
          out.insert("v", *v);
          return out;
        }
      throw InputError(fmt::format("{}: expected a number or an array of 3 numbers, got {}", where,
                                   node ? type_name(*node) : "'" + value + "'"));
    case Kind::Numbers:
      if (node && node->is_array()) return *doc;
      throw InputError(fmt::format("{}: expected an array of numbers like [0, 0.1, 1], got {}",
                                   where, node ? type_name(*node) : "'" + value + "'"));
  }
  return out;
}

std::vector<std::string> names_of(const std::vector<KeySpec>& keys) {
  std::vector<std::string> out;
  for (const auto& k : keys) out.emplace_back(k.name);
  return out;
}

//! The table that receives the key: [table], or element `index` of [[table]] (appending when
//! index equals the current size). Creates what is missing.
toml::table& target_table(toml::table& root, const TableSpec& spec, bool indexed,
                          const std::string& index, const std::string& where) {
  const std::string name(spec.name);
  if (!indexed) {
    if (!root.contains(name)) root.insert(name, toml::table{});
    toml::table* t = root.get_as<toml::table>(name);
    if (!t && spec.may_repeat)
      throw InputError(fmt::format("{}: the deck has [[{}]] tables; address one as {}.INDEX.KEY",
                                   where, name, name));
    if (!t) throw InputError(fmt::format("{}: '{}' in the deck is not a table", where, name));
    return *t;
  }
  if (!root.contains(name)) root.insert(name, toml::array{});
  toml::array* arr = root.get_as<toml::array>(name);
  if (!arr && spec.may_repeat)
    throw InputError(fmt::format("{}: the deck has one [{}] table; its keys are written {}.KEY",
                                 where, name, name));
  if (!arr || (!arr->empty() && !arr->is_array_of_tables()))
    throw InputError(fmt::format("{}: '{}' in the deck is not an array of tables", where, name));
  const std::size_t i = std::stoul(index);
  if (i > arr->size())
    throw InputError(fmt::format("{}: index {} out of range, the deck has {} [[{}]] table{}", where,
                                 i, arr->size(), name, arr->size() == 1 ? "" : "s"));
  if (i == arr->size()) arr->push_back(toml::table{});
  return *arr->get_as<toml::table>(i);
}

bool is_index(const std::string& s) {
  if (s.empty() || s.size() > 6) return false;
  for (char c : s)
    if (!std::isdigit(static_cast<unsigned char>(c))) return false;
  return true;
}

//! Applies one override; returns the dotted path of the key it set.
std::string apply_one(toml::table& root, const std::string& text) {
  const std::string where = "--set " + printable(text);
  const std::size_t eq = text.find('=');
  const std::string key = trim(text.substr(0, eq));
  const std::string value = eq == std::string::npos ? "" : trim(text.substr(eq + 1));
  std::vector<std::string> parts = split_dots(key);
  bool bad_syntax = eq == std::string::npos || key.empty() || value.empty() ||
                    std::any_of(text.begin(), text.end(), is_control);
  for (const auto& p : parts) bad_syntax = bad_syntax || p.empty();
  if (bad_syntax)
    throw InputError(
        fmt::format("{}: expected key=value on one line, e.g. material.youngs_modulus=2e5 or "
                    "geometry.0.radius=0.3",
                    where));

  std::vector<std::string> tables;
  for (const auto& t : schema()) tables.emplace_back(t.name);
  const TableSpec* spec = find_table(parts[0]);
  if (!spec)
    throw InputError(
        fmt::format("{}: unknown key '{}'{}", where, key, suggestion(parts[0], tables)));
  const bool indexed = spec->is_array || (spec->may_repeat && parts.size() == 3);
  if (indexed && (parts.size() != 3 || !is_index(parts[1])))
    throw InputError(fmt::format("{}: unknown key '{}' ([[{}]] keys are written {}.INDEX.KEY)",
                                 where, key, spec->name, spec->name));
  if (!indexed && parts.size() != 2)
    throw InputError(fmt::format(
        "{}: unknown key '{}' ([{}] keys are written {}.KEY{})", where, key, spec->name, spec->name,
        spec->may_repeat
            ? ", [[" + std::string(spec->name) + "]] keys " + std::string(spec->name) + ".INDEX.KEY"
            : ""));
  const std::string& leaf = parts.back();
  const KeySpec* key_spec = spec->find(leaf);
  if (!key_spec) {
    const std::string prefix = key.substr(0, key.size() - leaf.size());
    throw InputError(fmt::format("{}: unknown key '{}'{}", where, key,
                                 suggestion(leaf, names_of(spec->keys), prefix)));
  }
  toml::table node = typed_value(value, key_spec->kind, where);
  toml::table& target = target_table(root, *spec, indexed, indexed ? parts[1] : "", where);
  node.get("v")->visit([&](auto&& v) { target.insert_or_assign(leaf, v); });
  return indexed ? fmt::format("{}.{}.{}", parts[0], std::stoul(parts[1]), leaf) : key;
}

}  // namespace

std::map<std::string, std::string> apply_overrides(toml::table& root,
                                                   const std::vector<std::string>& overrides) {
  std::map<std::string, std::string> origins;
  for (const auto& text : overrides) origins[apply_one(root, text)] = text;
  return origins;
}

}  // namespace gen4d::deck
