#include "core/DeckText.hpp"

#include <fmt/format.h>

#include <cmath>

namespace gen4d {

std::string DeckText::number(double value) {
  if (std::isnan(value)) return "nan";
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  std::string s = fmt::format("{}", value);
  if (s.find_first_of(".eE") == std::string::npos) s += ".0";
  return s;
}

DeckText& DeckText::section(std::string_view name) {
  return raw(fmt::format("[{}]", name));
}

DeckText& DeckText::array(std::string_view name) {
  return raw(fmt::format("[[{}]]", name));
}

DeckText& DeckText::line(std::string_view key, std::string_view value) {
  return raw(fmt::format("{} = {}", key, value));
}

DeckText& DeckText::set(std::string_view key, double value) {
  return line(key, number(value));
}

DeckText& DeckText::set(std::string_view key, bool value) {
  return line(key, value ? "true" : "false");
}

DeckText& DeckText::set_integer(std::string_view key, long long value) {
  return line(key, fmt::format("{}", value));
}

DeckText& DeckText::set(std::string_view key, std::string_view value) {
  std::string quoted = "\"";
  for (const char c : value) {
    if (c == '"' || c == '\\') quoted += '\\';
    if (c == '\n') {
      quoted += "\\n";
      continue;
    }
    quoted += c;
  }
  return line(key, quoted + '"');
}

DeckText& DeckText::set(std::string_view key, const Vec3d& value) {
  return line(key,
              fmt::format("[{}, {}, {}]", number(value[0]), number(value[1]), number(value[2])));
}

DeckText& DeckText::raw(std::string_view text) {
  text_ += text;
  if (!text.empty() && text.back() != '\n') text_ += '\n';
  return *this;
}

DeckText BeamDeck::text() const {
  DeckText d;
  d.section("simulation").set("dt", dt).set("end_time", end_time);
  if (gravity) d.set("gravity", *gravity);
  d.section("domain").set("voxel_size", voxel_size).set("padding", padding);
  d.array("geometry").set("type", "box").set("lo", lo).set("hi", hi);
  d.section("material");
  if (!law.empty()) d.set("model", law);
  if (!target.empty()) d.set("target", target);
  d.set("youngs_modulus", youngs_modulus)
      .set("poisson_ratio", poisson_ratio)
      .set("density", density)
      .append(material);
  if (!method.empty() || !solver.str().empty()) {
    d.section("solver");
    if (!method.empty()) d.set("method", method);
    d.append(solver);
  }
  d.array("fixed").set("lo", fixed_lo).set("hi", fixed_hi);
  return d;
}

}  // namespace gen4d
