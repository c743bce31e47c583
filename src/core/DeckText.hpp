//! Builds deck TOML text in code: for drivers and tests that make decks on the fly.
//!
//! Numbers print so that they read back exactly (shortest round-trip form; a double always as a
//! TOML float, an integer as a TOML integer). Example, a clamped beam under a tip load:
//!
//!     BeamDeck beam;
//!     beam.hi = {0.5, 0.1, 0.1};
//!     beam.law = "stvk";
//!     beam.solver.set("relaxation", "jacobi");
//!     const Config cfg = parse_deck(beam.text()
//!                                       .array("force")
//!                                       .set("lo", Vec3d{0.49, -1, -1})
//!                                       .set("hi", Vec3d{1, 1, 1})
//!                                       .set("force", Vec3d{0, 0, -1})
//!                                       .str(),
//!                                   "<beam>", ".");
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <type_traits>

#include "core/Config.hpp"

namespace gen4d {

//! Deck text written line by line: table headers, `key = value` lines and raw text.
class DeckText {
 public:
  //! `[name]`.
  DeckText& section(std::string_view name);
  //! `[[name]]`: one more entry of an array of tables.
  DeckText& array(std::string_view name);
  DeckText& set(std::string_view key, double value);
  DeckText& set(std::string_view key, bool value);
  DeckText& set(std::string_view key, std::string_view value);
  DeckText& set(std::string_view key, const char* value) {
    return set(key, std::string_view(value));
  }
  DeckText& set(std::string_view key, const std::string& value) {
    return set(key, std::string_view(value));
  }
  DeckText& set(std::string_view key, const Vec3d& value);
  //! Integers (int, long, ...) print as TOML integers.
  template <class I, std::enable_if_t<std::is_integral_v<I> && !std::is_same_v<I, bool>, int> = 0>
  DeckText& set(std::string_view key, I value) {
    return set_integer(key, static_cast<long long>(value));
  }
  //! Text appended as it is (a newline is added when it lacks one).
  DeckText& raw(std::string_view text);
  //! Appends another builder's lines (e.g. extra keys for the current table).
  DeckText& append(const DeckText& other) { return raw(other.text_); }

  const std::string& str() const { return text_; }

  //! `value` as a TOML float that reads back to the same double.
  static std::string number(double value);

 private:
  DeckText& set_integer(std::string_view key, long long value);
  DeckText& line(std::string_view key, std::string_view value);
  std::string text_;
};

//! The box-shaped beam the validation and benchmark drivers share: `[simulation]`,
//! `[domain]`, one box `[[geometry]]`, `[material]`, `[solver]` and one `[[fixed]]` box
//! (by default the end x <= 0.001). Empty strings and unset optionals leave their key out
//! (the deck default applies); `material` and `solver` hold extra keys for those tables.
struct BeamDeck {
  double dt = 0.01, end_time = 0.01;
  std::optional<Vec3d> gravity;
  double voxel_size = 0.0125;
  long padding = 0;
  Vec3d lo{0, 0, 0}, hi{0.5, 0.1, 0.1};
  std::string law;     //!< material.model
  std::string target;  //!< material.target
  double youngs_modulus = 1e6, poisson_ratio = 0.3, density = 1000;
  std::string method;  //!< solver.method
  DeckText material, solver;
  Vec3d fixed_lo{-1, -1, -1}, fixed_hi{0.001, 1, 1};

  //! The deck; further tables (forces, kinematic regions) can be appended to the result.
  DeckText text() const;
};

}  // namespace gen4d
