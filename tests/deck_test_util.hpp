//! Deck text for tests: core/DeckText with the tables the tests write most, so a test states
//! its values and nothing else.
#pragma once

#include <array>
#include <string>
#include <utility>
#include <vector>

#include "core/DeckText.hpp"

namespace gen4d::test {

//! The keys of one table, each with its value as TOML text.
using Keys = std::vector<std::pair<std::string, std::string>>;

//! A number, or an array of three, as TOML in its shortest exact form.
inline std::string toml(double v) {
  return DeckText::number(v);
}
inline std::string toml(const Vec3d& v) {
  return "[" + toml(v[0]) + ", " + toml(v[1]) + ", " + toml(v[2]) + "]";
}
//! A TOML string.
inline std::string quoted(const std::string& s) {
  return "\"" + s + "\"";
}

//! TOML text of a deck, table by table in the order of the calls.
class TestDeck {
 public:
  //! A `[name]` table, or an `[[name]]` entry when `name` is written "[name]".
  TestDeck& table(const std::string& name, const Keys& keys = {}) {
    if (name.front() == '[')
      text_.array(name.substr(1, name.size() - 2));
    else
      text_.section(name);
    for (const auto& [key, value] : keys) text_.raw(key + " = " + value);
    return *this;
  }
  //! [simulation]: time step, end time, then `more` (gravity, name).
  TestDeck& simulation(double dt, double end_time, const Keys& more = {}) {
    return table("simulation", join({{"dt", toml(dt)}, {"end_time", toml(end_time)}}, more));
  }
  //! [simulation] gravity = [0, 0, 0].
  static std::pair<std::string, std::string> no_gravity() { return {"gravity", "[0, 0, 0]"}; }
  //! [solver] method = "mpm".
  TestDeck& mpm() { return table("solver", {{"method", quoted("mpm")}}); }
  //! [domain]: the voxel (or MPM cell) size, then `more` (padding).
  TestDeck& domain(double voxel_size, const Keys& more = {}) {
    return table("domain", join({{"voxel_size", toml(voxel_size)}}, more));
  }
  //! [domain] without padding: every grid node belongs to the object.
  TestDeck& unpadded(double voxel_size) { return domain(voxel_size, {{"padding", "0"}}); }
  //! A [[geometry]] box.
  TestDeck& box(const Vec3d& lo, const Vec3d& hi) {
    return table("[geometry]", {{"type", quoted("box")}, {"lo", toml(lo)}, {"hi", toml(hi)}});
  }
  //! [material]: `head` (model, target) first, then the elastic constants, then `more`.
  TestDeck& material(double youngs_modulus, double poisson_ratio, double density,
                     const Keys& head = {}, const Keys& more = {}) {
    return table("material", join(join(head, {{"youngs_modulus", toml(youngs_modulus)},
                                              {"poisson_ratio", toml(poisson_ratio)},
                                              {"density", toml(density)}}),
                                  more));
  }
  //! A [[fixed]] clamp of everything at x <= `x` (the beams' root face).
  TestDeck& clamp(double x = 0.001) { return region("fixed", {-1, -1, -1}, {x, 1, 1}); }
  //! An [[name]] region table (force, traction, kinematic, fixed) over [lo, hi], then `keys`.
  TestDeck& region(const std::string& name, const Vec3d& lo, const Vec3d& hi,
                   const Keys& keys = {}) {
    return table("[" + name + "]", join({{"lo", toml(lo)}, {"hi", toml(hi)}}, keys));
  }
  const std::string& str() const { return text_.str(); }
  operator std::string() const { return str(); }  // NOLINT: a deck is its text

 private:
  static Keys join(Keys a, const Keys& b) {
    a.insert(a.end(), b.begin(), b.end());
    return a;
  }
  DeckText text_;
};

//! The beam of the static cantilever and bending-frequency tests: 0.4 x 0.04 x 0.04 m on
//! 0.01 m voxels (40 x 4 x 4), E = 1e6 Pa, nu = 0, no gravity, clamped at x = 0.
inline BeamDeck slender_beam() {
  BeamDeck b;
  b.gravity = Vec3d{0, 0, 0};
  b.voxel_size = 0.01;
  b.hi = {0.4, 0.04, 0.04};
  b.target = "analytic";
  b.poisson_ratio = 0;
  return b;
}

//! `deck` with 0.01 N down on the slender beam's tip layer, then `more` (start, end).
inline std::string with_tip_load(DeckText deck, const Keys& more = {}) {
  deck.array("force").set("lo", Vec3d{0.399, -1, -1}).set("hi", Vec3d{1, 1, 1});
  deck.set("force", Vec3d{0, 0, -0.01});
  for (const auto& [key, value] : more) deck.raw(key + " = " + value);
  return deck.str();
}

}  // namespace gen4d::test
