//! Internals of the deck parser: the key schema, error locations and checked typed reads.
#pragma once

#include <toml++/toml.h>

#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "core/Config.hpp"

namespace gen4d::deck {

//! What a key holds; decides how a --set value is parsed and how the key is read.
//! A key's value: string, number, integer, [x, y, z], [numbers...], or a number or [x, y, z].
enum class Kind { String, Number, Integer, Vec3, Numbers, NumberOrVec3 };

struct KeySpec {
  std::string_view name;
  Kind kind;
};

//! A top-level table of the deck. Array tables ([[geometry]]) list the union of the keys of
//! their elements; type-specific geometry keys are checked by the geometry reader.
struct TableSpec {
  std::string_view name;
  bool is_array;
  std::vector<KeySpec> keys;
  //! [name] or [[name]]: one table, or several (--set addresses them as name.INDEX.KEY).
  bool may_repeat = false;
  const KeySpec* find(std::string_view key) const;
};

const std::vector<TableSpec>& schema();
const TableSpec* find_table(std::string_view name);

//! " (did you mean 'PREFIXx'?)" for the candidate closest to `word` (edit distance <= 2, or
//! containing it), else "".
std::string suggestion(std::string_view word, const std::vector<std::string>& candidates,
                       std::string_view prefix = "");

//! "string", "integer", "float", "boolean", "array", "table", "date", ...
std::string type_name(const toml::node& node);

//! Where a message points: the --set override that supplied a key, else FILE:LINE or FILE.
class Locator {
 public:
  Locator(std::string source, std::map<std::string, std::string> override_origins)
      : source_(std::move(source)), origins_(std::move(override_origins)) {}
  const std::string& source() const { return source_; }
  //! Every key path set by --set, with the override text that set it.
  const std::map<std::string, std::string>& origins() const { return origins_; }
  std::string at(const toml::node* node, const std::string& path) const;
  [[noreturn]] void fail(const toml::node* node, const std::string& path,
                         const std::string& message) const;

 private:
  std::string source_;
  std::map<std::string, std::string> origins_;  //!< key path -> "key=value" that set it
};

//! One table of the deck being read under a dotted path ("material", "geometry.0").
//! Every read checks presence, type and finiteness and throws a located InputError.
class Section {
 public:
  Section(const Locator& loc, toml::table* table, std::string path, const toml::node* header)
      : loc_(loc), table_(table), path_(std::move(path)), header_(header) {}

  bool present() const { return table_ != nullptr; }
  bool has(std::string_view key) const { return node(key) != nullptr; }
  const toml::node* node(std::string_view key) const;
  std::string key_path(std::string_view key) const;

  //! Rejects keys absent from `allowed`, the earliest in the file first.
  void reject_unknown(const std::vector<std::string>& allowed) const;

  double number(std::string_view key) const;
  double number(std::string_view key, double fallback) const;
  int integer(std::string_view key) const;
  int integer(std::string_view key, int fallback) const;
  std::string string(std::string_view key) const;
  std::string string(std::string_view key, const std::string& fallback) const;
  Vec3d vec3(std::string_view key) const;
  Vec3d vec3(std::string_view key, const Vec3d& fallback) const;
  //! A non-empty array of finite numbers.
  std::vector<double> numbers(std::string_view key) const;
  //! A string that must be one of `choices`.
  std::string choice(std::string_view key, const std::string& fallback,
                     const std::vector<std::string>& choices) const;

  //! Overwrites a string key (used to store resolved file paths in the final deck text).
  void replace(std::string_view key, const std::string& value);

  //! "FILE:LINE" (or "--set KEY=VALUE") of a key that is present.
  std::string where(std::string_view key) const;
  [[noreturn]] void fail(std::string_view key, const std::string& message) const;
  //! A problem of the table as a whole, located at its header.
  [[noreturn]] void fail_table(const std::string& message) const;
  void check(bool ok, std::string_view key, const std::string& message) const {
    if (!ok) fail(key, message);
  }

 private:
  const toml::node& required(std::string_view key) const;

  const Locator& loc_;
  toml::table* table_;
  std::string path_;
  const toml::node* header_;
};

//! Applies "key=value" overrides to the parsed deck. Returns, for every key set, the override
//! text that set it (so later messages can point at it). Throws InputError on bad syntax,
//! unknown keys or values of the wrong kind.
std::map<std::string, std::string> apply_overrides(toml::table& root,
                                                   const std::vector<std::string>& overrides);

}  // namespace gen4d::deck
