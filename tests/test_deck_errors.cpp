// Malformed decks and overrides: each must throw one InputError line naming file, line and key.
#include "test_deck_common.hpp"

namespace gen4d::test {
namespace {

//! Loads `text` as `name` and checks the message: one line, "NAME:LINE: " (or "NAME: " when
//! line is 0), the key, and a detail of what is wrong.
void expect_error(const std::string& name, const std::string& text, int line,
                  const std::string& key, const std::string& detail,
                  const std::vector<std::string>& overrides = {}) {
  const std::string msg = load_error(name, text, overrides);
  SCOPED_TRACE("message: " + msg);
  ASSERT_FALSE(msg.empty()) << name << " was accepted";
  EXPECT_EQ(msg.find('\n'), std::string::npos);
  const std::string where = "/" + name + (line > 0 ? ":" + std::to_string(line) : "") + ": ";
  EXPECT_NE(msg.find(where), std::string::npos) << "expected location '" << where << "'";
  EXPECT_NE(msg.find("'" + key + "'"), std::string::npos) << "expected key '" << key << "'";
  EXPECT_NE(msg.find(detail), std::string::npos) << "expected detail '" << detail << "'";
}

//! The full deck with the line holding `needle` replaced, and the line number of the change.
struct Edit {
  std::string text;
  int line;
};
Edit edit(const std::string& needle, const std::string& line) {
  return {replace_line(kFullDeck, needle, line), line_of(kFullDeck, needle)};
}

//! expect_error on the full deck with the line holding `needle` replaced by `line`, located at
//! that line, or `below` lines under it (a key the replacement adds).
void expect_edit_error(const std::string& name, const std::string& needle, const std::string& line,
                       const std::string& key, const std::string& detail, int below = 0) {
  const Edit e = edit(needle, line);
  expect_error(name, e.text, e.line + below, key, detail);
}

TEST(DeckErrors, UnknownKey) {
  expect_edit_error("unknown_key.toml", "density = 1000", "density = 1000\ncolour = \"red\"",
                    "material.colour", "unknown key", 1);
}

TEST(DeckErrors, TypoSuggestsKey) {
  expect_edit_error("typo.toml", "youngs_modulus = 1e6", "youngs_modlus = 1e6",
                    "material.youngs_modlus", "did you mean 'material.youngs_modulus'?");
  expect_edit_error("abbreviation.toml", "poisson_ratio = 0.3", "poisson = 0.3", "material.poisson",
                    "did you mean 'material.poisson_ratio'?");
}

TEST(DeckErrors, UnknownTableSuggestsTable) {
  expect_edit_error("unknown_table.toml", "[material]", "[materials]", "materials",
                    "unknown table 'materials' (did you mean 'material'?)");
  expect_edit_error("unknown_table2.toml", "[output]", "[postprocess]", "postprocess",
                    "unknown table");
}

TEST(DeckErrors, KeyAboveTablesSuggestsItsTable) {
  const std::string text = "end_time = 2\n" + kFullDeck;
  expect_error("stray_key.toml", text, 1, "end_time", "did you mean 'simulation.end_time'");
}

TEST(DeckErrors, WrongType) {
  expect_edit_error("wrong_type.toml", "density = 1000", "density = \"heavy\"", "material.density",
                    "expected a number, got string");
  expect_edit_error("wrong_type2.toml", "name = \"beam\"", "name = 3", "simulation.name",
                    "expected a string, got integer");
  expect_edit_error("wrong_type3.toml", "[solver]", "[[solver]]", "solver", "expected a table");
  expect_edit_error("wrong_type4.toml", "[[fixed]]", "[fixed]", "fixed",
                    "expected an array of tables");
}

TEST(DeckErrors, MissingRequiredKeyPointsAtTableHeader) {
  auto e = edit("dt = 1e-3", "");
  expect_error("missing_key.toml", e.text, line_of(kFullDeck, "[simulation]"), "simulation.dt",
               "missing required key");
  auto f = edit("type = \"sphere\"", "");
  expect_error("missing_type.toml", f.text, line_of(kFullDeck, "center = ") - 2, "geometry.1.type",
               "missing required key");
}

TEST(DeckErrors, MissingTableHasNoLine) {
  std::string text = kFullDeck;
  const auto begin = text.find("[material]"), end = text.find("[solver]");
  text.erase(begin, end - begin);
  expect_error("missing_table.toml", text, 0, "material.youngs_modulus", "missing required key");
}

TEST(DeckErrors, NonPositiveModulus) {
  expect_edit_error("negative_modulus.toml", "youngs_modulus = 1e6", "youngs_modulus = -1e6",
                    "material.youngs_modulus", "must be > 0");
}

TEST(DeckErrors, PoissonRatioBounds) {
  for (const std::string v : {"0.5", "-1", "0.7"}) {
    expect_edit_error("poisson.toml", "poisson_ratio = 0.3", "poisson_ratio = " + v,
                      "material.poisson_ratio", "must be in (-1, 0.5), got " + v);
  }
}

TEST(DeckErrors, NonPositiveTimeStep) {
  for (const std::string v : {"0", "-1e-3"}) {
    expect_edit_error("dt.toml", "dt = 1e-3", "dt = " + v, "simulation.dt", "must be > 0");
  }
  expect_edit_error("end_time.toml", "end_time = 0.5", "end_time = 1e-4", "simulation.end_time",
                    "must be >= simulation.dt");
}

TEST(DeckErrors, NotFinite) {
  expect_edit_error("nan.toml", "youngs_modulus = 1e6", "youngs_modulus = nan",
                    "material.youngs_modulus", "must be finite");
  expect_edit_error("inf.toml", "gravity = [0, 0, -9.81]", "gravity = [0, inf, -9.81]",
                    "simulation.gravity", "must be finite");
}

TEST(DeckErrors, VectorOfTwo) {
  expect_edit_error("vec2.toml", "gravity = [0, 0, -9.81]", "gravity = [0, -9.81]",
                    "simulation.gravity", "expected an array of 3 numbers, got 2 elements");
  expect_edit_error("vec_str.toml", "center = [1, 0.1, 0.1]", "center = [1, \"a\", 0.1]",
                    "geometry.1.center", "element 1 must be a number, got string");
}

TEST(DeckErrors, NoGeometry) {
  std::string text = kFullDeck;
  const auto begin = text.find("[[geometry]]"), end = text.find("[material]");
  text.erase(begin, end - begin);
  expect_error("no_geometry.toml", text, 0, "geometry", "missing required key");
  const std::string empty = "geometry = []\n" + text;
  expect_error("empty_geometry.toml", empty, 1, "geometry", "at least one [[geometry]]");
}

TEST(DeckErrors, BadGeometryType) {
  expect_edit_error(
      "geometry_type.toml", "type = \"sphere\"", "type = \"spere\"", "geometry.1.type",
      "must be one of box, sphere, capsule, cylinder, mesh, vdb, splats, got 'spere' (did "
      "you mean "
      "'sphere'?)");
}

TEST(DeckErrors, KeyOfAnotherGeometryType) {
  expect_edit_error("foreign_key.toml", "hi = [1, 0.2, 0.2]", "hi = [1, 0.2, 0.2]\nradius = 0.1",
                    "geometry.0.radius", "not a key of geometry type 'box'", 1);
}

TEST(DeckErrors, EmptyBoxes) {
  expect_edit_error("box_lo_hi.toml", "hi = [1, 0.2, 0.2]", "hi = [1, 0.2, 0]", "geometry.0.hi",
                    "must be > lo");
  expect_edit_error("fixed_lo_hi.toml", "hi = [0.05, 0.3, 0.3]", "hi = [-0.2, 0.3, 0.3]",
                    "fixed.0.hi", "must be > lo");
}

TEST(DeckErrors, MeshFile) {
  expect_edit_error("missing_mesh.toml", "file = \"assets/bunny.obj\"",
                    "file = \"assets/missing.obj\"", "geometry.3.file", "assets/missing.obj");
  expect_edit_error("mesh_ext.toml", "file = \"assets/bunny.obj\"", "file = \"assets/bunny.ply\"",
                    "geometry.3.file", "must be an .obj or .stl");
  expect_edit_error("missing_vdb.toml", "file = \"assets/cloud.vdb\"",
                    "file = \"nowhere/cloud.vdb\"", "geometry.4.file", "file not found");
}

TEST(DeckErrors, TomlSyntaxHasLineAndColumn) {
  auto e = edit("density = 1000", "density = 1000 kg");
  const std::string msg = load_error("syntax.toml", e.text);
  EXPECT_NE(msg.find("/syntax.toml:" + std::to_string(e.line) + ":"), std::string::npos) << msg;
  EXPECT_NE(msg.find(": TOML syntax error: "), std::string::npos) << msg;
  EXPECT_EQ(msg.find('\n'), std::string::npos);
}

TEST(DeckErrors, NonIntegralInteger) {
  expect_edit_error("padding.toml", "padding = 2.0", "padding = 2.5", "domain.padding",
                    "expected an integer, got 2.5");
}

TEST(DeckErrors, OtherRanges) {
  expect_edit_error("modes.toml", "subspace_modes = 24", "subspace_modes = 65",
                    "solver.subspace_modes", "must be in [0, 64]");
  expect_edit_error("force_end.toml", "end = 0.3", "end = 0.1", "force.0.end", "must be > start");
  expect_edit_error("relaxation.toml", "relaxation = \"cg\"", "relaxation = \"gauss\"",
                    "solver.relaxation", "must be one of jacobi, chebyshev, cg");
  expect_edit_error("ratio.toml", "chebyshev_ratio = 0.1", "chebyshev_ratio = 1.0",
                    "solver.chebyshev_ratio", "must be in [0, 1)");
  expect_edit_error("keep.toml", "checkpoint_keep = 3", "checkpoint_keep = 0",
                    "output.checkpoint_keep", "must be >= 1");
}

TEST(DeckErrors, Colliders) {
  expect_edit_error("collider_type.toml", "type = \"plane\"", "type = \"plan\"", "collider.0.type",
                    "must be one of plane, box, got 'plan' (did you mean 'plane'?)");
  expect_edit_error("collider_normal.toml", "normal = [0, 0, 2]", "normal = [0, 0, 0]",
                    "collider.0.normal", "must not be the zero vector");
  expect_edit_error("collider_box.toml", "hi = [3, 1, 1]", "hi = [3, 1, -1]", "collider.1.hi",
                    "must be > lo");
  expect_edit_error("collider_friction.toml", "friction = 0.3", "friction = -0.1",
                    "collider.0.friction", "must be >= 0, got -0.1");
  expect_edit_error("collider_foreign.toml", "friction = 0.3", "friction = 0.3\nlo = [0, 0, 0]",
                    "collider.0.lo", "not a key of collider type 'plane'", 1);
  auto j = edit("normal = [0, 0, 2]", "");
  expect_error("collider_missing.toml", j.text, line_of(kFullDeck, "type = \"plane\"") - 1,
               "collider.0.normal", "missing required key");
  expect_edit_error("collider_typo.toml", "normal = [0, 0, 2]",
                    "normal = [0, 0, 2]\nfrictoin = 0.1", "collider.0.frictoin",
                    "did you mean 'collider.0.friction'?", 1);
}

TEST(DeckErrors, Tractions) {
  expect_edit_error("traction_box.toml", "hi = [1.2, 0.4, 0.4]", "hi = [0.9, 0.4, 0.4]",
                    "traction.0.hi", "must be > lo");
  expect_edit_error("traction_end.toml", "end = 0.2", "end = 0.01", "traction.0.end",
                    "must be > start (0.05), got 0.01");
  std::string text = replace_line(kFullDeck, "traction = [0, 1, 0]", "");
  text = replace_line(text, "pressure = 1e3", "");
  expect_error("traction_empty.toml", text, line_of(kFullDeck, "[[traction]]"), "traction.0",
               "needs 'traction' (vec3, Pa) or 'pressure' (Pa)");
  expect_edit_error("traction_pressure.toml", "pressure = 1e3", "pressure = \"high\"",
                    "traction.0.pressure", "expected a number, got string");
}

TEST(DeckErrors, MissingDeckFile) {
  try {
    load_deck((scratch_dir() / "no_such_deck.toml").string(), {});
    FAIL() << "missing deck accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no_such_deck.toml: "), std::string::npos);
  }
}

//! The message of parse_deck(full deck, overrides), which must fail.
std::string override_error(const std::vector<std::string>& overrides) {
  try {
    parse_deck(kFullDeck, "<test deck>", scratch_dir().string(), overrides);
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "overrides accepted: " << overrides.front();
  return "";
}

TEST(DeckErrors, BadOverrideSyntax) {
  for (const std::string s :
       {"material.youngs_modulus", "=5", "material..density=1", "material.density=", " . =3"}) {
    const std::string msg = override_error({s});
    EXPECT_EQ(msg.rfind("--set " + s + ": expected key=value", 0), 0u) << msg;
  }
  // A value smuggling a second line is refused, and the message itself stays one line.
  const std::string msg = override_error({"material.density=1\nsimulation.dt=2"});
  EXPECT_EQ(msg.rfind("--set material.density=1\\x0asimulation.dt=2: expected key=value", 0), 0u)
      << msg;
}

TEST(DeckErrors, OverrideOfUnknownKey) {
  std::string msg = override_error({"material.youngs=2e5"});
  EXPECT_EQ(msg,
            "--set material.youngs=2e5: unknown key 'material.youngs' (did you mean "
            "'material.youngs_modulus'?)");
  msg = override_error({"materials.density=5"});
  EXPECT_NE(msg.find("unknown key 'materials.density' (did you mean 'material'?)"),
            std::string::npos)
      << msg;
  msg = override_error({"geometry.radius=0.3"});
  EXPECT_NE(msg.find("geometry.INDEX.KEY"), std::string::npos) << msg;
  msg = override_error({"geometry.9.radius=0.3"});
  EXPECT_NE(msg.find("index 9 out of range"), std::string::npos) << msg;
}

TEST(DeckErrors, OverrideOfWrongKind) {
  EXPECT_EQ(override_error({"material.youngs_modulus=abc"}),
            "--set material.youngs_modulus=abc: expected a number, got 'abc'");
  EXPECT_EQ(override_error({"simulation.gravity=1"})
                .rfind("--set simulation.gravity=1: expected "
                       "an array of 3 numbers",
                       0),
            0u);
  EXPECT_EQ(override_error({"solver.max_outer=two"}),
            "--set solver.max_outer=two: expected an integer, got 'two'");
}

TEST(DeckErrors, OverrideValuesAreValidatedAndBlamed) {
  EXPECT_EQ(override_error({"material.poisson_ratio=0.7"}),
            "--set material.poisson_ratio=0.7: key 'material.poisson_ratio': must be in (-1, "
            "0.5), got 0.7");
  EXPECT_EQ(override_error({"domain.padding=1.5"}),
            "--set domain.padding=1.5: key 'domain.padding': expected an integer, got 1.5");
  const std::string msg = override_error({"geometry.0.radius=0.3"});
  EXPECT_EQ(msg.rfind("--set geometry.0.radius=0.3: key 'geometry.0.radius': not a key of "
                      "geometry type 'box'",
                      0),
            0u)
      << msg;
}

TEST(DeckErrors, EmbeddedSourceName) {
  try {
    parse_deck(replace_line(kFullDeck, "density = 1000", "density = 0"), "<embedded default>",
               scratch_dir().string(), {});
    FAIL() << "accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              "<embedded default>:" + std::to_string(line_of(kFullDeck, "density = 1000")) +
                  ": key 'material.density': must be > 0, got 0");
  }
}

TEST(DeckErrors, NeuralMaterialKeys) {
  expect_edit_error("neural_not_neural.toml", "density = 1000",
                    "density = 1000\nneural_weights = \"mtl.h5\"", "material.neural_weights",
                    "only applies to target = \"neural\"", 1);
  expect_edit_error("neural_missing.toml", "target = \"arap\"",
                    "target = \"neural\"\nneural_weights = \"nowhere.h5\"",
                    "material.neural_weights", "file not found", 1);
  const std::string g =
      replace_line(replace_line(kFullDeck, "target = \"arap\"", "target = \"neural\""),
                   "model = \"corotated\"", "model = \"linear\"");
  expect_error("neural_linear.toml", g, line_of(kFullDeck, "model = \"corotated\""),
               "material.model", "needs a hyperelastic law");
}

}  // namespace
}  // namespace gen4d::test
