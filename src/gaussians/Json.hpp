//! A small strict JSON (RFC 8259) reader and writer: 3DGS cameras.json, PhysGaussian configs.
#pragma once

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

namespace gen4d::gaussians {

//! One JSON value with the line it starts on (1-based; 0 for values built in code).
class JsonValue {
 public:
  enum class Type { Null, Bool, Number, String, Array, Object };

  JsonValue() = default;
  static JsonValue null();
  static JsonValue boolean(bool b);
  static JsonValue number(double v);
  static JsonValue string(std::string s);
  static JsonValue array(std::vector<JsonValue> items = {});
  //! Members in file order; keys are unique (the reader rejects duplicates).
  static JsonValue object(std::vector<std::pair<std::string, JsonValue>> members = {});

  Type type() const { return type_; }
  int line() const { return line_; }
  bool is_null() const { return type_ == Type::Null; }
  bool is_bool() const { return type_ == Type::Bool; }
  bool is_number() const { return type_ == Type::Number; }
  bool is_string() const { return type_ == Type::String; }
  bool is_array() const { return type_ == Type::Array; }
  bool is_object() const { return type_ == Type::Object; }

  //! Accessors; std::logic_error when the value has another type (check type() first).
  bool as_bool() const;
  double as_number() const;
  const std::string& as_string() const;
  const std::vector<JsonValue>& items() const;
  const std::vector<std::pair<std::string, JsonValue>>& members() const;
  //! Object member `key`, or nullptr when absent (logic_error if this is not an object).
  const JsonValue* find(const std::string& key) const;

  //! Appends to an array / object built in code.
  void push_back(JsonValue v);
  void set(const std::string& key, JsonValue v);

  //! Compact JSON text; numbers with 17 significant digits so they read back exactly.
  //! std::logic_error for a NaN or infinite number (JSON has none).
  std::string dump(int indent = 0) const;

 private:
  friend class JsonParser;
  Type type_ = Type::Null;
  int line_ = 0;
  bool bool_ = false;
  double number_ = 0;
  std::string string_;
  std::vector<JsonValue> items_;
  std::vector<std::pair<std::string, JsonValue>> members_;
  void dump_to(std::string& out, int indent, int depth) const;
};

//! "null", "boolean", "number", "string", "array", "object".
const char* json_type_name(JsonValue::Type t);

//! Parses JSON text. InputError "SOURCE:LINE: ..." for any syntax error (trailing commas,
//! comments, NaN, leading zeros, bad escapes, control characters in strings, unpaired
//! surrogates, duplicate keys, nesting deeper than 512, trailing content).
JsonValue parse_json(const std::string& text, const std::string& source);

//! Reads and parses a file; InputError naming the file when it cannot be read.
JsonValue read_json_file(const std::string& path);

//! Writes `value.dump(indent)` to `path` through a temporary and a rename; RuntimeError when it
//! cannot be written.
void write_json_file(const std::string& path, const JsonValue& value, int indent = 2);

}  // namespace gen4d::gaussians
