//! Shared fixtures of the deck tests: a full valid deck, scratch files, text surgery.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/Deck.hpp"
#include "core/Error.hpp"

namespace gen4d::test {

//! A deck that uses every table and every geometry type; tests edit single lines of it.
inline const std::string kFullDeck = R"(# gen4d test deck
[simulation]
name = "beam"
dt = 1e-3
end_time = 0.5
gravity = [0, 0, -9.81]

[domain]
voxel_size = 0.05
padding = 2.0

[[geometry]]
type = "box"
lo = [0, 0, 0]
hi = [1, 0.2, 0.2]

[[geometry]]
type = "sphere"
center = [1, 0.1, 0.1]
radius = 0.15

[[geometry]]
type = "capsule"
a = [0, 0.1, 0.1]
b = [0, 0.1, 0.5]
radius = 0.05

[[geometry]]
type = "mesh"
file = "assets/bunny.obj"
scale = 2
translate = [0.5, 0, 0]

[[geometry]]
type = "vdb"
file = "assets/cloud.vdb"
grid = "surface"

[material]
model = "corotated"
target = "arap"
youngs_modulus = 1e6
poisson_ratio = 0.3
density = 1000

[solver]
relaxation = "cg"
jacobi_omega = 0.8
chebyshev_ratio = 0.1
max_sweeps = 200
inner_tolerance = 1e-7
subspace_modes = 24
max_outer = 5
outer_tolerance = 1e-4
accuracy_tolerance = 1e-2
max_extra_outer = 3

[[fixed]]
lo = [-0.1, -0.1, -0.1]
hi = [0.05, 0.3, 0.3]

[[force]]
lo = [0.95, -0.1, -0.1]
hi = [1.1, 0.3, 0.3]
force = [0, 0, -50]
start = 0.1
end = 0.3

[[collider]]
type = "plane"
point = [0, 0, -0.1]
normal = [0, 0, 2]
friction = 0.3

[[collider]]
type = "box"
lo = [2, -1, -1]
hi = [3, 1, 1]

[[traction]]
lo = [0.9, -0.2, -0.2]
hi = [1.2, 0.4, 0.4]
traction = [0, 1, 0]
pressure = 1e3
start = 0.05
end = 0.2

[output]
dir = "out/beam"
frame_interval = 0.01
checkpoint_every = 100
checkpoint_keep = 3
progress_interval = 5
)";

//! Scratch folder under the build tree holding decks and the assets they reference.
inline std::filesystem::path scratch_dir() {
  const auto dir = std::filesystem::path(GEN4D_BINARY_DIR) / "tests" / "deck_scratch";
  std::filesystem::create_directories(dir / "assets");
  for (const char* asset : {"assets/bunny.obj", "assets/cloud.vdb"}) {
    if (std::filesystem::exists(dir / asset)) continue;
    std::ofstream(dir / asset) << "# placeholder; only existence is checked by the deck\n";
  }
  return dir;
}

inline std::string write_deck(const std::string& name, const std::string& text) {
  const auto path = scratch_dir() / name;
  std::ofstream(path) << text;
  return path.string();
}

//! 1-based line of the first occurrence of `needle` (0 if absent).
inline int line_of(const std::string& text, const std::string& needle) {
  const auto pos = text.find(needle);
  if (pos == std::string::npos) return 0;
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + pos, '\n'));
}

//! `text` with the whole line containing `needle` replaced by `line` (may hold newlines,
//! or be empty to delete the line).
inline std::string replace_line(const std::string& text, const std::string& needle,
                                const std::string& line) {
  const auto pos = text.find(needle);
  if (pos == std::string::npos) throw std::logic_error("test deck has no '" + needle + "'");
  const auto begin = text.rfind('\n', pos) + 1;
  const auto end = text.find('\n', pos);
  return text.substr(0, begin) + line + (line.empty() ? "" : "\n") + text.substr(end + 1);
}

//! The InputError message of loading `text` (written to `name`) with `overrides`, or "" if
//! it loaded.
inline std::string load_error(const std::string& name, const std::string& text,
                              const std::vector<std::string>& overrides = {}) {
  const std::string path = write_deck(name, text);
  try {
    load_deck(path, overrides);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace gen4d::test
