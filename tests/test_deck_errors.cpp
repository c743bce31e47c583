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

TEST(DeckErrors, UnknownKey) {
  auto e = edit("density = 1000", "density = 1000\ncolour = \"red\"");
  expect_error("unknown_key.toml", e.text, e.line + 1, "material.colour", "unknown key");
}

TEST(DeckErrors, TypoSuggestsKey) {
  auto e = edit("youngs_modulus = 1e6", "youngs_modlus = 1e6");
  expect_error("typo.toml", e.text, e.line, "material.youngs_modlus",
               "did you mean 'material.youngs_modulus'?");
  auto f = edit("poisson_ratio = 0.3", "poisson = 0.3");
  expect_error("abbreviation.toml", f.text, f.line, "material.poisson",
               "did you mean 'material.poisson_ratio'?");
}

TEST(DeckErrors, UnknownTableSuggestsTable) {
  auto e = edit("[material]", "[materials]");
  expect_error("unknown_table.toml", e.text, e.line, "materials",
               "unknown table 'materials' (did you mean 'material'?)");
  auto f = edit("[output]", "[postprocess]");
  expect_error("unknown_table2.toml", f.text, f.line, "postprocess", "unknown table");
}

TEST(DeckErrors, KeyAboveTablesSuggestsItsTable) {
  const std::string text = "end_time = 2\n" + kFullDeck;
  expect_error("stray_key.toml", text, 1, "end_time", "did you mean 'simulation.end_time'");
}

TEST(DeckErrors, WrongType) {
  auto e = edit("density = 1000", "density = \"heavy\"");
  expect_error("wrong_type.toml", e.text, e.line, "material.density",
               "expected a number, got string");
  auto f = edit("name = \"beam\"", "name = 3");
  expect_error("wrong_type2.toml", f.text, f.line, "simulation.name",
               "expected a string, got integer");
  auto g = edit("[solver]", "[[solver]]");
  expect_error("wrong_type3.toml", g.text, g.line, "solver", "expected a table");
  auto h = edit("[[fixed]]", "[fixed]");
  expect_error("wrong_type4.toml", h.text, h.line, "fixed", "expected an array of tables");
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
  auto e = edit("youngs_modulus = 1e6", "youngs_modulus = -1e6");
  expect_error("negative_modulus.toml", e.text, e.line, "material.youngs_modulus", "must be > 0");
}

TEST(DeckErrors, PoissonRatioBounds) {
  for (const std::string v : {"0.5", "-1", "0.7"}) {
    auto e = edit("poisson_ratio = 0.3", "poisson_ratio = " + v);
    expect_error("poisson.toml", e.text, e.line, "material.poisson_ratio",
                 "must be in (-1, 0.5), got " + v);
  }
}

TEST(DeckErrors, NonPositiveTimeStep) {
  for (const std::string v : {"0", "-1e-3"}) {
    auto e = edit("dt = 1e-3", "dt = " + v);
    expect_error("dt.toml", e.text, e.line, "simulation.dt", "must be > 0");
  }
  auto f = edit("end_time = 0.5", "end_time = 1e-4");
  expect_error("end_time.toml", f.text, f.line, "simulation.end_time", "must be >= simulation.dt");
}

TEST(DeckErrors, NotFinite) {
  auto e = edit("youngs_modulus = 1e6", "youngs_modulus = nan");
  expect_error("nan.toml", e.text, e.line, "material.youngs_modulus", "must be finite");
  auto f = edit("gravity = [0, 0, -9.81]", "gravity = [0, inf, -9.81]");
  expect_error("inf.toml", f.text, f.line, "simulation.gravity", "must be finite");
}

TEST(DeckErrors, VectorOfTwo) {
  auto e = edit("gravity = [0, 0, -9.81]", "gravity = [0, -9.81]");
  expect_error("vec2.toml", e.text, e.line, "simulation.gravity",
               "expected an array of 3 numbers, got 2 elements");
  auto f = edit("center = [1, 0.1, 0.1]", "center = [1, \"a\", 0.1]");
  expect_error("vec_str.toml", f.text, f.line, "geometry.1.center",
               "element 1 must be a number, got string");
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
  auto e = edit("type = \"sphere\"", "type = \"spere\"");
  expect_error("geometry_type.toml", e.text, e.line, "geometry.1.type",
               "must be one of box, sphere, capsule, cylinder, mesh, vdb, splats, got 'spere' (did "
               "you mean "
               "'sphere'?)");
}

TEST(DeckErrors, KeyOfAnotherGeometryType) {
  auto e = edit("hi = [1, 0.2, 0.2]", "hi = [1, 0.2, 0.2]\nradius = 0.1");
  expect_error("foreign_key.toml", e.text, e.line + 1, "geometry.0.radius",
               "not a key of geometry type 'box'");
}

TEST(DeckErrors, EmptyBoxes) {
  auto e = edit("hi = [1, 0.2, 0.2]", "hi = [1, 0.2, 0]");
  expect_error("box_lo_hi.toml", e.text, e.line, "geometry.0.hi", "must be > lo");
  auto f = edit("hi = [0.05, 0.3, 0.3]", "hi = [-0.2, 0.3, 0.3]");
  expect_error("fixed_lo_hi.toml", f.text, f.line, "fixed.0.hi", "must be > lo");
}

TEST(DeckErrors, MeshFile) {
  auto e = edit("file = \"assets/bunny.obj\"", "file = \"assets/missing.obj\"");
  expect_error("missing_mesh.toml", e.text, e.line, "geometry.3.file", "assets/missing.obj");
  auto f = edit("file = \"assets/bunny.obj\"", "file = \"assets/bunny.ply\"");
  expect_error("mesh_ext.toml", f.text, f.line, "geometry.3.file", "must be an .obj or .stl");
  auto g = edit("file = \"assets/cloud.vdb\"", "file = \"nowhere/cloud.vdb\"");
  expect_error("missing_vdb.toml", g.text, g.line, "geometry.4.file", "file not found");
}

TEST(DeckErrors, TomlSyntaxHasLineAndColumn) {
  auto e = edit("density = 1000", "density = 1000 kg");
  const std::string msg = load_error("syntax.toml", e.text);
  EXPECT_NE(msg.find("/syntax.toml:" + std::to_string(e.line) + ":"), std::string::npos) << msg;
  EXPECT_NE(msg.find(": TOML syntax error: "), std::string::npos) << msg;
  EXPECT_EQ(msg.find('\n'), std::string::npos);
}

TEST(DeckErrors, NonIntegralInteger) {
  auto e = edit("padding = 2.0", "padding = 2.5");
  expect_error("padding.toml", e.text, e.line, "domain.padding", "expected an integer, got 2.5");
}

TEST(DeckErrors, OtherRanges) {
  auto e = edit("subspace_modes = 24", "subspace_modes = 65");
  expect_error("modes.toml", e.text, e.line, "solver.subspace_modes", "must be in [0, 64]");
  auto f = edit("end = 0.3", "end = 0.1");
  expect_error("force_end.toml", f.text, f.line, "force.0.end", "must be > start");
  auto g = edit("relaxation = \"cg\"", "relaxation = \"gauss\"");
  expect_error("relaxation.toml", g.text, g.line, "solver.relaxation",
               "must be one of jacobi, chebyshev, cg");
  auto r = edit("chebyshev_ratio = 0.1", "chebyshev_ratio = 1.0");
  expect_error("ratio.toml", r.text, r.line, "solver.chebyshev_ratio", "must be in [0, 1)");
  auto h = edit("checkpoint_keep = 3", "checkpoint_keep = 0");
  expect_error("keep.toml", h.text, h.line, "output.checkpoint_keep", "must be >= 1");
}

TEST(DeckErrors, Colliders) {
  auto e = edit("type = \"plane\"", "type = \"plan\"");
  expect_error("collider_type.toml", e.text, e.line, "collider.0.type",
               "must be one of plane, box, got 'plan' (did you mean 'plane'?)");
  auto f = edit("normal = [0, 0, 2]", "normal = [0, 0, 0]");
  expect_error("collider_normal.toml", f.text, f.line, "collider.0.normal",
               "must not be the zero vector");
  auto g = edit("hi = [3, 1, 1]", "hi = [3, 1, -1]");
  expect_error("collider_box.toml", g.text, g.line, "collider.1.hi", "must be > lo");
  auto h = edit("friction = 0.3", "friction = -0.1");
  expect_error("collider_friction.toml", h.text, h.line, "collider.0.friction",
               "must be >= 0, got -0.1");
  auto i = edit("friction = 0.3", "friction = 0.3\nlo = [0, 0, 0]");
  expect_error("collider_foreign.toml", i.text, i.line + 1, "collider.0.lo",
               "not a key of collider type 'plane'");
  auto j = edit("normal = [0, 0, 2]", "");
  expect_error("collider_missing.toml", j.text, line_of(kFullDeck, "type = \"plane\"") - 1,
               "collider.0.normal", "missing required key");
  auto k = edit("normal = [0, 0, 2]", "normal = [0, 0, 2]\nfrictoin = 0.1");
  expect_error("collider_typo.toml", k.text, k.line + 1, "collider.0.frictoin",
               "did you mean 'collider.0.friction'?");
}

TEST(DeckErrors, Tractions) {
  auto e = edit("hi = [1.2, 0.4, 0.4]", "hi = [0.9, 0.4, 0.4]");
  expect_error("traction_box.toml", e.text, e.line, "traction.0.hi", "must be > lo");
  auto f = edit("end = 0.2", "end = 0.01");
  expect_error("traction_end.toml", f.text, f.line, "traction.0.end",
               "must be > start (0.05), got 0.01");
  std::string text = replace_line(kFullDeck, "traction = [0, 1, 0]", "");
  text = replace_line(text, "pressure = 1e3", "");
  expect_error("traction_empty.toml", text, line_of(kFullDeck, "[[traction]]"), "traction.0",
               "needs 'traction' (vec3, Pa) or 'pressure' (Pa)");
  auto g = edit("pressure = 1e3", "pressure = \"high\"");
  expect_error("traction_pressure.toml", g.text, g.line, "traction.0.pressure",
               "expected a number, got string");
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
  auto e = edit("density = 1000", "density = 1000\nneural_weights = \"mtl.h5\"");
  expect_error("neural_not_neural.toml", e.text, e.line + 1, "material.neural_weights",
               "only applies to target = \"neural\"");
  auto f = edit("target = \"arap\"", "target = \"neural\"\nneural_weights = \"nowhere.h5\"");
  expect_error("neural_missing.toml", f.text, f.line + 1, "material.neural_weights",
               "file not found");
  const std::string g =
      replace_line(replace_line(kFullDeck, "target = \"arap\"", "target = \"neural\""),
                   "model = \"corotated\"", "model = \"linear\"");
  expect_error("neural_linear.toml", g, line_of(kFullDeck, "model = \"corotated\""),
               "material.model", "needs a hyperelastic law");
}

}  // namespace
}  // namespace gen4d::test
