#include "gaussians/Json.hpp"

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "core/Error.hpp"
#include "core/TextFile.hpp"
#include "io/Xdmf.hpp"

namespace gen4d::gaussians {

JsonValue JsonValue::null() {
  return JsonValue();
}
JsonValue JsonValue::boolean(bool b) {
  JsonValue v;
  v.type_ = Type::Bool;
  v.bool_ = b;
  return v;
}
JsonValue JsonValue::number(double x) {
  JsonValue v;
  v.type_ = Type::Number;
  v.number_ = x;
  return v;
}
JsonValue JsonValue::string(std::string s) {
  JsonValue v;
  v.type_ = Type::String;
  v.string_ = std::move(s);
  return v;
}
JsonValue JsonValue::array(std::vector<JsonValue> items) {
  JsonValue v;
  v.type_ = Type::Array;
  v.items_ = std::move(items);
  return v;
}
JsonValue JsonValue::object(std::vector<std::pair<std::string, JsonValue>> members) {
  JsonValue v;
  v.type_ = Type::Object;
  v.members_ = std::move(members);
  return v;
}

namespace {
void expect_type(JsonValue::Type have, JsonValue::Type want) {
  if (have != want)
    throw std::logic_error(std::string("JSON value is a ") + json_type_name(have) + ", not a " +
                           json_type_name(want));
}
}  // namespace

bool JsonValue::as_bool() const {
  expect_type(type_, Type::Bool);
  return bool_;
}
double JsonValue::as_number() const {
  expect_type(type_, Type::Number);
  return number_;
}
const std::string& JsonValue::as_string() const {
  expect_type(type_, Type::String);
  return string_;
}
const std::vector<JsonValue>& JsonValue::items() const {
  expect_type(type_, Type::Array);
  return items_;
}
const std::vector<std::pair<std::string, JsonValue>>& JsonValue::members() const {
  expect_type(type_, Type::Object);
  return members_;
}
const JsonValue* JsonValue::find(const std::string& key) const {
  expect_type(type_, Type::Object);
  for (const auto& m : members_)
    if (m.first == key) return &m.second;
  return nullptr;
}
void JsonValue::push_back(JsonValue v) {
  expect_type(type_, Type::Array);
  items_.push_back(std::move(v));
}
void JsonValue::set(const std::string& key, JsonValue v) {
  expect_type(type_, Type::Object);
  for (auto& m : members_)
    if (m.first == key) {
      m.second = std::move(v);
      return;
    }
  members_.emplace_back(key, std::move(v));
}

const char* json_type_name(JsonValue::Type t) {
  switch (t) {
    case JsonValue::Type::Null:
      return "null";
    case JsonValue::Type::Bool:
      return "boolean";
    case JsonValue::Type::Number:
      return "number";
    case JsonValue::Type::String:
      return "string";
    case JsonValue::Type::Array:
      return "array";
    case JsonValue::Type::Object:
      return "object";
  }
  return "?";
}

namespace {

void dump_string(std::string& out, const std::string& s) {
  out += '"';
  for (unsigned char c : s) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\r':
        out += "\\r";
        break;
      case '\t':
        out += "\\t";
        break;
      case '\b':
        out += "\\b";
        break;
      case '\f':
        out += "\\f";
        break;
      default:
        if (c < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", c);
          out += buf;
        } else {
          out += static_cast<char>(c);
        }
    }
  }
  out += '"';
}

void newline(std::string& out, int indent, int depth) {
  if (indent <= 0) return;
  out += '\n';
  out.append(static_cast<std::size_t>(indent) * depth, ' ');
}

//! `open`, then `count` items written by item(i) one per line at depth + 1 (or ", "-separated
//! when indent is 0), then `close`.
template <class Item>
void dump_items(std::string& out, int indent, int depth, char open, char close, std::size_t count,
                Item&& item) {
  out += open;
  for (std::size_t i = 0; i < count; ++i) {
    if (i) out += indent > 0 ? "," : ", ";
    newline(out, indent, depth + 1);
    item(i);
  }
  if (count > 0) newline(out, indent, depth);
  out += close;
}

}  // namespace

void JsonValue::dump_to(std::string& out, int indent, int depth) const {
  switch (type_) {
    case Type::Null:
      out += "null";
      break;
    case Type::Bool:
      out += bool_ ? "true" : "false";
      break;
    case Type::Number: {
      if (!std::isfinite(number_)) throw std::logic_error("JSON cannot hold NaN or infinity");
      char buf[32];
      // Integers print without an exponent; everything else round-trips with 17 digits.
      if (number_ == std::floor(number_) && std::fabs(number_) < 1e15)
        std::snprintf(buf, sizeof buf, "%.0f", number_);
      else
        std::snprintf(buf, sizeof buf, "%.17g", number_);
      out += buf;
      break;
    }
    case Type::String:
      dump_string(out, string_);
      break;
    case Type::Array:
      dump_items(out, indent, depth, '[', ']', items_.size(),
                 [&](std::size_t i) { items_[i].dump_to(out, indent, depth + 1); });
      break;
    case Type::Object:
      dump_items(out, indent, depth, '{', '}', members_.size(), [&](std::size_t i) {
        dump_string(out, members_[i].first);
        out += ": ";
        members_[i].second.dump_to(out, indent, depth + 1);
      });
      break;
  }
}

std::string JsonValue::dump(int indent) const {
  std::string out;
  dump_to(out, indent, 0);
  return out;
}

//! Recursive-descent parser over the whole text.
class JsonParser {
 public:
  JsonParser(const std::string& text, const std::string& source) : t_(text), src_(source) {}

  JsonValue parse_document() {
    skip_ws();
    JsonValue v = parse_value(0);
    skip_ws();
    if (pos_ != t_.size()) fail("unexpected content after the JSON value");
    return v;
  }

 private:
  static constexpr int kMaxDepth = 512;
  const std::string& t_;
  const std::string& src_;
  std::size_t pos_ = 0;
  int line_ = 1;

  [[noreturn]] void fail(const std::string& what) const {
    throw InputError(src_ + ":" + std::to_string(line_) + ": malformed JSON: " + what);
  }

  void skip_ws() {
    while (pos_ < t_.size()) {
      const char c = t_[pos_];
      if (c == '\n') {
        ++line_;
      } else if (c != ' ' && c != '\t' && c != '\r') {
        return;
      }
      ++pos_;
    }
  }

  std::string describe_here() const {
    if (pos_ >= t_.size()) return "end of file";
    const unsigned char c = static_cast<unsigned char>(t_[pos_]);
    if (c < 0x20 || c >= 0x7f) {
      char buf[16];
      std::snprintf(buf, sizeof buf, "byte 0x%02x", c);
      return buf;
    }
    return std::string("'") + static_cast<char>(c) + "'";
  }

  JsonValue parse_value(int depth) {
    if (depth > kMaxDepth) fail("nesting deeper than " + std::to_string(kMaxDepth));
    if (pos_ >= t_.size()) fail("expected a value, found end of file");
    const int line = line_;
    JsonValue v;
    const char c = t_[pos_];
    if (c == '{') {
      v = parse_object(depth);
    } else if (c == '[') {
      v = parse_array(depth);
    } else if (c == '"') {
      v = JsonValue::string(parse_string());
    } else if (c == '-' || (c >= '0' && c <= '9')) {
      v = JsonValue::number(parse_number());
    } else if (t_.compare(pos_, 4, "true") == 0) {
      pos_ += 4;
      v = JsonValue::boolean(true);
    } else if (t_.compare(pos_, 5, "false") == 0) {
      pos_ += 5;
      v = JsonValue::boolean(false);
    } else if (t_.compare(pos_, 4, "null") == 0) {
      pos_ += 4;
      v = JsonValue::null();
    } else {
      fail("expected a value, found " + describe_here());
    }
    v.line_ = line;
    return v;
  }

  //! The items of an object or array from its opening bracket through `close`, each read by
  //! `item`; `what` names the container in messages.
  template <class Item>
  void parse_items(char close, const char* what, Item&& item) {
    ++pos_;  // '{' or '['
    skip_ws();
    if (pos_ < t_.size() && t_[pos_] == close) {
      ++pos_;
      return;
    }
    for (;;) {
      skip_ws();
      item();
      skip_ws();
      if (pos_ < t_.size() && t_[pos_] == ',') {
        ++pos_;
        continue;
      }
      if (pos_ < t_.size() && t_[pos_] == close) {
        ++pos_;
        return;
      }
      fail(std::string("expected ',' or '") + close + "' in " + what + ", found " +
           describe_here());
    }
  }

  JsonValue parse_object(int depth) {
    JsonValue obj = JsonValue::object();
    parse_items('}', "an object", [&] {
      if (pos_ >= t_.size() || t_[pos_] != '"')
        fail("expected a member name in double quotes, found " + describe_here());
      std::string key = parse_string();
      for (const auto& m : obj.members_)
        if (m.first == key) fail("duplicate key \"" + key + "\"");
      skip_ws();
      if (pos_ >= t_.size() || t_[pos_] != ':')
        fail("expected ':' after \"" + key + "\", found " + describe_here());
      ++pos_;
      skip_ws();
      JsonValue v = parse_value(depth + 1);
      obj.members_.emplace_back(std::move(key), std::move(v));
    });
    return obj;
  }

  JsonValue parse_array(int depth) {
    JsonValue arr = JsonValue::array();
    parse_items(']', "an array", [&] { arr.items_.push_back(parse_value(depth + 1)); });
    return arr;
  }

  unsigned hex4() {
    if (pos_ + 4 > t_.size()) fail("truncated \\u escape");
    unsigned v = 0;
    for (int i = 0; i < 4; ++i) {
      const char c = t_[pos_++];
      v <<= 4;
      if (c >= '0' && c <= '9')
        v |= static_cast<unsigned>(c - '0');
      else if (c >= 'a' && c <= 'f')
        v |= static_cast<unsigned>(c - 'a' + 10);
      else if (c >= 'A' && c <= 'F')
        v |= static_cast<unsigned>(c - 'A' + 10);
      else
        fail("bad hex digit in a \\u escape");
    }
    return v;
  }

  static void append_utf8(std::string& out, unsigned cp) {
    if (cp < 0x80) {
      out += static_cast<char>(cp);
    } else if (cp < 0x800) {
      out += static_cast<char>(0xc0 | (cp >> 6));
      out += static_cast<char>(0x80 | (cp & 0x3f));
    } else if (cp < 0x10000) {
      out += static_cast<char>(0xe0 | (cp >> 12));
      out += static_cast<char>(0x80 | ((cp >> 6) & 0x3f));
      out += static_cast<char>(0x80 | (cp & 0x3f));
    } else {
      out += static_cast<char>(0xf0 | (cp >> 18));
      out += static_cast<char>(0x80 | ((cp >> 12) & 0x3f));
      out += static_cast<char>(0x80 | ((cp >> 6) & 0x3f));
      out += static_cast<char>(0x80 | (cp & 0x3f));
    }
  }

  std::string parse_string() {
    ++pos_;  // opening quote
    std::string out;
    for (;;) {
      if (pos_ >= t_.size()) fail("unterminated string");
      const unsigned char c = static_cast<unsigned char>(t_[pos_++]);
      if (c == '"') return out;
      if (c < 0x20) fail(c == '\n' ? "unterminated string" : "control character in a string");
      if (c != '\\') {
        out += static_cast<char>(c);
        continue;
      }
      if (pos_ >= t_.size()) fail("unterminated string");
      const char e = t_[pos_++];
      switch (e) {
        case '"':
          out += '"';
          break;
        case '\\':
          out += '\\';
          break;
        case '/':
          out += '/';
          break;
        case 'b':
          out += '\b';
          break;
        case 'f':
          out += '\f';
          break;
        case 'n':
          out += '\n';
          break;
        case 'r':
          out += '\r';
          break;
        case 't':
          out += '\t';
          break;
        case 'u': {
          unsigned cp = hex4();
          if (cp >= 0xdc00 && cp <= 0xdfff) fail("unpaired low surrogate in a \\u escape");
          if (cp >= 0xd800 && cp <= 0xdbff) {
            if (pos_ + 2 > t_.size() || t_[pos_] != '\\' || t_[pos_ + 1] != 'u')
              fail("unpaired high surrogate in a \\u escape");
            pos_ += 2;
            const unsigned lo = hex4();
            if (lo < 0xdc00 || lo > 0xdfff) fail("unpaired high surrogate in a \\u escape");
            cp = 0x10000 + ((cp - 0xd800) << 10) + (lo - 0xdc00);
          }
          append_utf8(out, cp);
          break;
        }
        default:
          fail(std::string("bad escape '\\") + e + "' in a string");
      }
    }
  }

  double parse_number() {
    const std::size_t start = pos_;
    auto digit = [&] { return pos_ < t_.size() && t_[pos_] >= '0' && t_[pos_] <= '9'; };
    if (t_[pos_] == '-') ++pos_;
    if (!digit()) fail("bad number: a digit must follow '-'");
    if (t_[pos_] == '0') {
      ++pos_;
      if (digit()) fail("bad number: leading zero");
    } else {
      while (digit()) ++pos_;
    }
    if (pos_ < t_.size() && t_[pos_] == '.') {
      ++pos_;
      if (!digit()) fail("bad number: a digit must follow '.'");
      while (digit()) ++pos_;
    }
    if (pos_ < t_.size() && (t_[pos_] == 'e' || t_[pos_] == 'E')) {
      ++pos_;
      if (pos_ < t_.size() && (t_[pos_] == '+' || t_[pos_] == '-')) ++pos_;
      if (!digit()) fail("bad number: a digit must follow the exponent");
      while (digit()) ++pos_;
    }
    const std::string token = t_.substr(start, pos_ - start);
    const double v = std::strtod(token.c_str(), nullptr);
    if (!std::isfinite(v)) fail("number " + token + " is out of range");
    return v;
  }
};

JsonValue parse_json(const std::string& text, const std::string& source) {
  return JsonParser(text, source).parse_document();
}

JsonValue read_json_file(const std::string& path) {
  return parse_json(read_whole_file(path, "JSON file"), path);
}

void write_json_file(const std::string& path, const JsonValue& value, int indent) {
  io::write_text_atomically(path, value.dump(indent) + "\n");
}

}  // namespace gen4d::gaussians
