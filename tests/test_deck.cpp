// Valid decks: values, defaults, --set overrides and the parse(text) round trip of restarts.
#include "test_deck_common.hpp"

#include <sstream>

#include "core/DeckReader.hpp"

namespace gen4d::test {
namespace {

namespace fs = std::filesystem;

const std::string kMinimalDeck = R"(
[simulation]
dt = 0.01
end_time = 1

[domain]
voxel_size = 0.1

[[geometry]]
type = "sphere"
center = [0, 0, 0]
radius = 0.5

[material]
youngs_modulus = 1e5
poisson_ratio = 0.25
density = 500
)";

void expect_box(const BoxRegion& r, const Vec3d& lo, const Vec3d& hi) {
  EXPECT_EQ(r.lo, lo);
  EXPECT_EQ(r.hi, hi);
}

//! Field-by-field equality; exact, since a restart must reproduce the run bit for bit.
void expect_same(const Config& a, const Config& b) {
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.dt, b.dt);
  EXPECT_EQ(a.end_time, b.end_time);
  EXPECT_EQ(a.gravity, b.gravity);
  EXPECT_EQ(a.voxel_size, b.voxel_size);
  EXPECT_EQ(a.padding, b.padding);
  ASSERT_EQ(a.geometry.size(), b.geometry.size());
  for (std::size_t i = 0; i < a.geometry.size(); ++i) {
    const GeometryConfig &g = a.geometry[i], &h = b.geometry[i];
    EXPECT_EQ(g.type, h.type);
    EXPECT_EQ(g.lo, h.lo);
    EXPECT_EQ(g.hi, h.hi);
    EXPECT_EQ(g.center, h.center);
    EXPECT_EQ(g.radius, h.radius);
    EXPECT_EQ(g.a, h.a);
    EXPECT_EQ(g.b, h.b);
    EXPECT_EQ(g.file, h.file);
    EXPECT_EQ(g.grid, h.grid);
    EXPECT_EQ(g.scale, h.scale);
    EXPECT_EQ(g.translate, h.translate);
  }
  EXPECT_EQ(a.material.model, b.material.model);
  EXPECT_EQ(a.material.target, b.material.target);
  EXPECT_EQ(a.material.youngs_modulus, b.material.youngs_modulus);
  EXPECT_EQ(a.material.poisson_ratio, b.material.poisson_ratio);
  EXPECT_EQ(a.material.density, b.material.density);
  const SolverConfig &s = a.solver, &t = b.solver;
  EXPECT_EQ(s.relaxation, t.relaxation);
  EXPECT_EQ(s.jacobi_omega, t.jacobi_omega);
  EXPECT_EQ(s.chebyshev_ratio, t.chebyshev_ratio);
  EXPECT_EQ(s.max_sweeps, t.max_sweeps);
  EXPECT_EQ(s.inner_tolerance, t.inner_tolerance);
  EXPECT_EQ(s.subspace_modes, t.subspace_modes);
  EXPECT_EQ(s.max_outer, t.max_outer);
  EXPECT_EQ(s.outer_tolerance, t.outer_tolerance);
  EXPECT_EQ(s.accuracy_tolerance, t.accuracy_tolerance);
  EXPECT_EQ(s.max_extra_outer, t.max_extra_outer);
  EXPECT_EQ(s.anderson_depth, t.anderson_depth);
  EXPECT_EQ(s.method, t.method);
  ASSERT_EQ(a.fixed.size(), b.fixed.size());
  for (std::size_t i = 0; i < a.fixed.size(); ++i)
    expect_box(a.fixed[i].region, b.fixed[i].region.lo, b.fixed[i].region.hi);
  ASSERT_EQ(a.forces.size(), b.forces.size());
  for (std::size_t i = 0; i < a.forces.size(); ++i) {
    expect_box(a.forces[i].region, b.forces[i].region.lo, b.forces[i].region.hi);
    EXPECT_EQ(a.forces[i].force, b.forces[i].force);
    EXPECT_EQ(a.forces[i].start, b.forces[i].start);
    EXPECT_EQ(a.forces[i].end, b.forces[i].end);
  }
  ASSERT_EQ(a.colliders.size(), b.colliders.size());
  for (std::size_t i = 0; i < a.colliders.size(); ++i) {
    const ColliderConfig &c = a.colliders[i], &d = b.colliders[i];
    EXPECT_EQ(c.type, d.type);
    EXPECT_EQ(c.point, d.point);
    EXPECT_EQ(c.normal, d.normal);
    expect_box(c.box, d.box.lo, d.box.hi);
    EXPECT_EQ(c.friction, d.friction);
  }
  ASSERT_EQ(a.tractions.size(), b.tractions.size());
  for (std::size_t i = 0; i < a.tractions.size(); ++i) {
    const TractionConfig &t = a.tractions[i], &u = b.tractions[i];
    expect_box(t.region, u.region.lo, u.region.hi);
    EXPECT_EQ(t.traction, u.traction);
    EXPECT_EQ(t.pressure, u.pressure);
    EXPECT_EQ(t.start, u.start);
    EXPECT_EQ(t.end, u.end);
  }
  EXPECT_EQ(a.output.dir, b.output.dir);
  EXPECT_EQ(a.output.frame_interval, b.output.frame_interval);
  EXPECT_EQ(a.output.checkpoint_every, b.output.checkpoint_every);
  EXPECT_EQ(a.output.checkpoint_keep, b.output.checkpoint_keep);
  EXPECT_EQ(a.output.progress_interval, b.output.progress_interval);
}

TEST(Deck, FullDeckValues) {
  const std::string path = write_deck("full.toml", kFullDeck);
  const Config c = load_deck(path, {});
  EXPECT_EQ(c.source, path);
  EXPECT_EQ(c.name, "beam");
  EXPECT_EQ(c.dt, 1e-3);
  EXPECT_EQ(c.end_time, 0.5);
  EXPECT_EQ(c.gravity, (Vec3d{0, 0, -9.81}));
  EXPECT_EQ(c.voxel_size, 0.05);
  EXPECT_EQ(c.padding, 2);  // written 2.0
  ASSERT_EQ(c.geometry.size(), 5u);
  EXPECT_EQ(c.geometry[0].type, "box");
  EXPECT_EQ(c.geometry[0].lo, (Vec3d{0, 0, 0}));
  EXPECT_EQ(c.geometry[0].hi, (Vec3d{1, 0.2, 0.2}));
  EXPECT_EQ(c.geometry[1].type, "sphere");
  EXPECT_EQ(c.geometry[1].center, (Vec3d{1, 0.1, 0.1}));
  EXPECT_EQ(c.geometry[1].radius, 0.15);
  EXPECT_EQ(c.geometry[2].type, "capsule");
  EXPECT_EQ(c.geometry[2].a, (Vec3d{0, 0.1, 0.1}));
  EXPECT_EQ(c.geometry[2].b, (Vec3d{0, 0.1, 0.5}));
  EXPECT_EQ(c.geometry[2].radius, 0.05);
  EXPECT_EQ(c.geometry[3].type, "mesh");
  // Relative to the deck's folder, stored absolute.
  EXPECT_EQ(fs::path(c.geometry[3].file), fs::absolute(scratch_dir() / "assets/bunny.obj"));
  EXPECT_EQ(c.geometry[3].scale, 2.0);  // written 2
  EXPECT_EQ(c.geometry[3].translate, (Vec3d{0.5, 0, 0}));
  EXPECT_EQ(c.geometry[4].type, "vdb");
  EXPECT_EQ(fs::path(c.geometry[4].file), fs::absolute(scratch_dir() / "assets/cloud.vdb"));
  EXPECT_EQ(c.geometry[4].grid, "surface");
  EXPECT_EQ(c.geometry[4].scale, 1.0);
  EXPECT_EQ(c.material.model, "corotated");
  EXPECT_EQ(c.material.target, "arap");
  EXPECT_EQ(c.material.youngs_modulus, 1e6);
  EXPECT_EQ(c.material.poisson_ratio, 0.3);
  EXPECT_EQ(c.material.density, 1000.0);
  EXPECT_EQ(c.solver.relaxation, "cg");
  EXPECT_EQ(c.solver.jacobi_omega, 0.8);
  EXPECT_EQ(c.solver.chebyshev_ratio, 0.1);
  EXPECT_EQ(c.solver.max_sweeps, 200);
  EXPECT_EQ(c.solver.inner_tolerance, 1e-7);
  EXPECT_EQ(c.solver.subspace_modes, 24);
  EXPECT_EQ(c.solver.max_outer, 5);
  EXPECT_EQ(c.solver.outer_tolerance, 1e-4);
  EXPECT_EQ(c.solver.accuracy_tolerance, 1e-2);
  EXPECT_EQ(c.solver.max_extra_outer, 3);
  ASSERT_EQ(c.fixed.size(), 1u);
  expect_box(c.fixed[0].region, {-0.1, -0.1, -0.1}, {0.05, 0.3, 0.3});
  ASSERT_EQ(c.forces.size(), 1u);
  expect_box(c.forces[0].region, {0.95, -0.1, -0.1}, {1.1, 0.3, 0.3});
  EXPECT_EQ(c.forces[0].force, (Vec3d{0, 0, -50}));
  EXPECT_EQ(c.forces[0].start, 0.1);
  EXPECT_EQ(c.forces[0].end, 0.3);
  ASSERT_EQ(c.colliders.size(), 2u);
  EXPECT_EQ(c.colliders[0].type, "plane");
  EXPECT_EQ(c.colliders[0].point, (Vec3d{0, 0, -0.1}));
  EXPECT_EQ(c.colliders[0].normal, (Vec3d{0, 0, 2}));  // as written; colliders normalise it
  EXPECT_EQ(c.colliders[0].friction, 0.3);
  EXPECT_EQ(c.colliders[1].type, "box");
  expect_box(c.colliders[1].box, {2, -1, -1}, {3, 1, 1});
  EXPECT_EQ(c.colliders[1].friction, ColliderConfig{}.friction);
  EXPECT_EQ(ColliderConfig{}.friction, 0.5);  // the documented default
  ASSERT_EQ(c.tractions.size(), 1u);
  expect_box(c.tractions[0].region, {0.9, -0.2, -0.2}, {1.2, 0.4, 0.4});
  EXPECT_EQ(c.tractions[0].traction, (Vec3d{0, 1, 0}));
  EXPECT_EQ(c.tractions[0].pressure, 1e3);
  EXPECT_EQ(c.tractions[0].start, 0.05);
  EXPECT_EQ(c.tractions[0].end, 0.2);
  EXPECT_EQ(c.output.dir, "out/beam");
  EXPECT_EQ(c.output.frame_interval, 0.01);
  EXPECT_EQ(c.output.checkpoint_every, 100);
  EXPECT_EQ(c.output.checkpoint_keep, 3);
  EXPECT_EQ(c.output.progress_interval, 5.0);
}

TEST(Deck, MinimalDeckTakesDefaults) {
  const Config c = parse_deck(kMinimalDeck, "<minimal>", ".", {});
  const Config defaults;
  EXPECT_EQ(c.source, "<minimal>");
  EXPECT_EQ(c.name, "gen4d");
  EXPECT_EQ(c.gravity, (Vec3d{0, 0, -9.81}));
  EXPECT_EQ(c.padding, 1);
  EXPECT_EQ(c.material.model, "corotated");
  EXPECT_EQ(c.material.target, "arap");
  EXPECT_TRUE(c.fixed.empty());
  EXPECT_TRUE(c.forces.empty());
  EXPECT_TRUE(c.colliders.empty());
  EXPECT_TRUE(c.tractions.empty());
  Config expected = c;
  expected.solver = defaults.solver;
  expected.output = defaults.output;
  expect_same(c, expected);
  EXPECT_EQ(c.solver.max_sweeps, 100);
  EXPECT_EQ(c.output.dir, "gen4d-out");
}

TEST(Deck, OverridesChangeValues) {
  const std::string path = write_deck("override.toml", kFullDeck);
  const Config c =
      load_deck(path, {"material.youngs_modulus=2e5", "solver.relaxation=jacobi",
                       "simulation.gravity=[0,0,-1]", "geometry.1.radius=0.3", "force.0.end=0.45",
                       "output.dir=out/run 2", "simulation.name=123", "simulation.dt=.002",
                       " material.density = 800 ", "solver.max_sweeps=300.0"});
  EXPECT_EQ(c.material.youngs_modulus, 2e5);
  EXPECT_EQ(c.solver.relaxation, "jacobi");
  EXPECT_EQ(c.gravity, (Vec3d{0, 0, -1}));
  EXPECT_EQ(c.geometry[1].radius, 0.3);
  EXPECT_EQ(c.forces[0].end, 0.45);
  EXPECT_EQ(c.output.dir, "out/run 2");
  EXPECT_EQ(c.name, "123");
  EXPECT_EQ(c.dt, 0.002);
  EXPECT_EQ(c.material.density, 800.0);
  EXPECT_EQ(c.solver.max_sweeps, 300);
  // Untouched values stay.
  EXPECT_EQ(c.material.poisson_ratio, 0.3);
  EXPECT_EQ(c.geometry[1].center, (Vec3d{1, 0.1, 0.1}));
}

TEST(Deck, QuotedStringsAndLastOverrideWins) {
  const Config c = parse_deck(
      kFullDeck, "<deck>", scratch_dir().string(),
      {"solver.relaxation=\"jacobi\"", "solver.relaxation='cg'", "material.target=analytic"});
  EXPECT_EQ(c.solver.relaxation, "cg");
  EXPECT_EQ(c.material.target, "analytic");
}

TEST(Deck, OverridesAddKeysTablesAndElements) {
  const Config c =
      parse_deck(kMinimalDeck, "<minimal>", ".",
                 {"output.checkpoint_every=5", "solver.max_sweeps=50", "material.target=arap",
                  "fixed.0.lo=[-1,-1,-1]", "fixed.0.hi=[1,1,-0.4]", "force.0.lo=[-1,-1,0.4]",
                  "force.0.hi=[1,1,1]", "force.0.force=[0,0,2.5]", "force.0.start=0.5",
                  "geometry.1.type=box", "geometry.1.lo=[0,0,0]", "geometry.1.hi=[1,1,1]",
                  "collider.0.type=plane", "collider.0.point=[0,0,-1]", "collider.0.normal=[0,0,1]",
                  "traction.0.lo=[-1,-1,-1]", "traction.0.hi=[1,1,1]", "traction.0.pressure=5"});
  EXPECT_EQ(c.output.checkpoint_every, 5);
  EXPECT_EQ(c.solver.max_sweeps, 50);
  EXPECT_EQ(c.material.target, "arap");
  ASSERT_EQ(c.fixed.size(), 1u);
  expect_box(c.fixed[0].region, {-1, -1, -1}, {1, 1, -0.4});
  ASSERT_EQ(c.forces.size(), 1u);
  EXPECT_EQ(c.forces[0].force, (Vec3d{0, 0, 2.5}));
  EXPECT_EQ(c.forces[0].start, 0.5);
  EXPECT_EQ(c.forces[0].end, ForceConfig{}.end);  // forever
  ASSERT_EQ(c.geometry.size(), 2u);
  EXPECT_EQ(c.geometry[1].type, "box");
  EXPECT_EQ(c.geometry[1].hi, (Vec3d{1, 1, 1}));
  ASSERT_EQ(c.colliders.size(), 1u);
  EXPECT_EQ(c.colliders[0].point, (Vec3d{0, 0, -1}));
  EXPECT_EQ(c.colliders[0].friction, 0.5);
  ASSERT_EQ(c.tractions.size(), 1u);
  EXPECT_EQ(c.tractions[0].pressure, 5.0);
  EXPECT_EQ(c.tractions[0].traction, (Vec3d{0, 0, 0}));
  EXPECT_EQ(c.tractions[0].end, TractionConfig{}.end);
}

TEST(Deck, RoundTripReproducesConfig) {
  const std::string path = write_deck("roundtrip.toml", kFullDeck);
  const Config first = load_deck(path, {"material.poisson_ratio=0.1", "output.frame_interval=0.3",
                                        "simulation.gravity=[0.1, 0.2, -9.80665]"});
  // The text holds the overrides, so no overrides are needed to restart, and absolute asset
  // paths, so the restart may run from another folder.
  const Config again = parse_deck(first.text, "<restart>", "/", {});
  expect_same(first, again);
  EXPECT_EQ(again.material.poisson_ratio, 0.1);
  EXPECT_EQ(again.output.frame_interval, 0.3);
  EXPECT_EQ(again.text, first.text);
  // Numbers are stored in their shortest exact form, so the stored deck reads like the input.
  EXPECT_NE(first.text.find("\nvoxel_size = 0.05\n"), std::string::npos) << first.text;
  EXPECT_NE(first.text.find("\npoisson_ratio = 0.1\n"), std::string::npos) << first.text;
  EXPECT_NE(first.text.find("\ngravity = [0.1, 0.2, -9.80665]\n"), std::string::npos);
  EXPECT_EQ(first.text.find("[[force]]"), first.text.rfind("[[force]]"));

  const Config minimal = parse_deck(kMinimalDeck, "<minimal>", ".", {"domain.padding=3"});
  expect_same(minimal, parse_deck(minimal.text, "<restart>", ".", {}));
  EXPECT_EQ(minimal.padding, 3);
}

std::string read_readme() {
  std::ifstream in(fs::path(GEN4D_SOURCE_DIR) / "inputs" / "README.md");
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

TEST(Deck, SplatGeometryAndRender) {
  const auto dir = scratch_dir();
  std::ofstream(dir / "assets" / "object.ply") << "placeholder; only existence is checked\n";
  std::ofstream(dir / "assets" / "cameras.json") << "[]\n";
  const std::string text = kMinimalDeck + R"(
[[geometry]]
type = "splats"
file = "assets/object.ply"
scale = 2
translate = [0, 0, 1]
rotate_axis = [1, 0, 0]
rotate_degrees = 90
opacity_threshold = 0.1

[render]
center = [0, 0, 0.5]
azimuth = 30
elevation = 10
radius = 2.5
d_azimuth = 3
width = 320
height = 200
background = [0, 0, 0]
kinematics = "rigid_covariance"
covariance_update = "rate"
video = "mp4"
)";
  const Config c = load_deck(write_deck("splats.toml", text), {});
  ASSERT_EQ(c.geometry.size(), 2u);
  const GeometryConfig& g = c.geometry[1];
  EXPECT_EQ(g.type, "splats");
  EXPECT_EQ(fs::path(g.file), fs::absolute(dir / "assets" / "object.ply").lexically_normal());
  EXPECT_EQ(g.scale, 2);
  EXPECT_EQ(g.translate, (Vec3d{0, 0, 1}));
  EXPECT_EQ(g.rotate_axis, (Vec3d{1, 0, 0}));
  EXPECT_EQ(g.rotate_degrees, 90);
  EXPECT_EQ(g.opacity_threshold, 0.1);
  EXPECT_EQ(c.geometry[0].color, (Vec3d{0.75, 0.75, 0.75}));  // the sphere's default colour
  const RenderConfig& r = c.render;
  EXPECT_TRUE(r.enabled);
  EXPECT_EQ(r.camera, "orbit");
  EXPECT_EQ(r.center, (Vec3d{0, 0, 0.5}));
  EXPECT_EQ(r.azimuth, 30);
  EXPECT_EQ(r.elevation, 10);
  EXPECT_EQ(r.radius, 2.5);
  EXPECT_EQ(r.d_azimuth, 3);
  EXPECT_EQ(r.width, 320);
  EXPECT_EQ(r.height, 200);
  EXPECT_EQ(r.background, (Vec3d{0, 0, 0}));
  EXPECT_EQ(r.kinematics, "rigid_covariance");
  EXPECT_EQ(r.covariance_update, "rate");
  EXPECT_TRUE(r.mp4);
  // The stored deck re-reads to the same values from anywhere (restarts).
  const Config again = parse_deck(c.text, "<restart>", "/", {});
  EXPECT_EQ(again.geometry[1].file, g.file);
  EXPECT_EQ(again.geometry[1].rotate_degrees, 90);
  EXPECT_EQ(again.render.d_azimuth, 3);
  EXPECT_TRUE(again.render.mp4);
  EXPECT_FALSE(parse_deck(kMinimalDeck, "<minimal>", ".", {}).render.enabled);
  // Without camera, center or radius the orbit frames the object; a deck with splat geometry
  // renders without a [render] table.
  EXPECT_EQ(parse_deck(kMinimalDeck + "\n[render]\nwidth = 8\n", "<r>", ".", {}).render.camera,
            "auto");
  const std::string no_table = text.substr(0, text.find("[render]"));
  const Config implicit = load_deck(write_deck("splats_implicit.toml", no_table), {});
  EXPECT_TRUE(implicit.render.enabled);
  EXPECT_EQ(implicit.render.camera, "auto");

  // A cameras.json entry, resolved against the deck's folder, keeps its index.
  const std::string cam = kMinimalDeck + "\n[render]\ncamera = \"assets/cameras.json:3\"\n";
  const Config cc = load_deck(write_deck("splats_camera.toml", cam), {});
  EXPECT_EQ(cc.render.camera,
            fs::absolute(dir / "assets" / "cameras.json").lexically_normal().string() + ":3");
  EXPECT_EQ(parse_deck(cc.text, "<restart>", "/", {}).render.camera, cc.render.camera);
}

TEST(Deck, SnowMaterialKeysReachTheModel) {
  const std::string text = R"(
[simulation]
dt = 1e-4
end_time = 0.01

[solver]
method = "mpm"

[domain]
voxel_size = 0.02

[[geometry]]
type = "box"
lo = [0, 0, 0]
hi = [0.1, 0.1, 0.1]

[material]
model = "snow"
youngs_modulus = 1.4e5
poisson_ratio = 0.2
density = 400
critical_compression = 0.02
critical_stretch = 0.005
hardening_coefficient = 8
)";
  const Config c = parse_deck(text, "snow.toml", ".", {});
  EXPECT_EQ(c.material.model, "snow");
  EXPECT_EQ(c.material.params.at("critical_compression"), 0.02);
  EXPECT_EQ(c.material.params.at("critical_stretch"), 0.005);
  EXPECT_EQ(c.material.params.at("hardening_coefficient"), 8);
}

TEST(Deck, SplatAndRenderErrors) {
  const auto dir = scratch_dir();
  std::ofstream(dir / "assets" / "object.ply") << "placeholder\n";
  const std::string splats =
      kMinimalDeck + "\n[[geometry]]\ntype = \"splats\"\nfile = \"assets/object.ply\"\n";
  struct Case {
    std::string extra, needle;
  };
  const std::vector<Case> cases = {
      {"color = [1, 0, 0]\n", "geometry.1.color"},       // splats keep their trained colours
      {"opacity_threshold = 1\n", "must be in [0, 1)"},  // would drop every Gaussian
      {"rotate_axis = [0, 0, 0]\n", "must not be the zero vector"},
      {"\n[render]\ncamera = \"missing.json\"\n", "cameras file not found"},
      {"\n[render]\nwidth = 0\n", "render.width"},
      {"\n[render]\nelevation = 90\n", "render.elevation"},
      {"\n[render]\nkinematics = \"frozen\"\n", "render.kinematics"},
      {"\n[render]\nbackground = [2, 0, 0]\n", "colour channels must be in [0, 1]"},
      {"\n[render]\nvideo = \"gif\"\n", "render.video"},
  };
  for (const Case& c : cases) {
    const std::string msg = load_error("splat_error.toml", splats + c.extra);
    EXPECT_NE(msg.find(c.needle), std::string::npos) << c.extra << " -> " << msg;
    EXPECT_NE(msg.find("splat_error.toml:"), std::string::npos) << msg;
  }
  std::ofstream(dir / "assets" / "cameras.json") << "[]\n";
  const std::string msg = load_error(
      "splat_error.toml", splats + "\n[render]\ncamera = \"assets/cameras.json\"\nazimuth = 10\n");
  EXPECT_NE(msg.find("only applies to the orbit cameras"), std::string::npos) << msg;
  const std::string auto_msg =
      load_error("splat_error.toml", splats + "\n[render]\ncamera = \"auto\"\nradius = 2\n");
  EXPECT_NE(auto_msg.find("render.radius"), std::string::npos) << auto_msg;
  const std::string box_color =
      load_error("color_error.toml",
                 replace_line(kMinimalDeck, "radius = 0.5", "radius = 0.5\ncolor = [0.5, 1.5, 0]"));
  EXPECT_NE(box_color.find("geometry.0.color"), std::string::npos) << box_color;
}

TEST(Deck, BoxCellsPointMassesAndPreloads) {
  // voxel_size: one number (cubes) or three edges, also through --set.
  const Config cube = parse_deck(kMinimalDeck, "<d>", ".", {});
  EXPECT_EQ(cube.spacing, (Vec3d{0.1, 0.1, 0.1}));
  EXPECT_TRUE(cube.cubic_cells());
  const Config box = parse_deck(kMinimalDeck, "<d>", ".", {"domain.voxel_size=[0.1, 0.05, 0.02]"});
  EXPECT_EQ(box.spacing, (Vec3d{0.1, 0.05, 0.02}));
  EXPECT_EQ(box.voxel_size, 0.1);
  EXPECT_FALSE(box.cubic_cells());
  EXPECT_EQ(box.cell_edges(), box.spacing);
  Config refined = box;
  refined.voxel_size = 0.05;  // a copy refined by setting voxel_size alone
  EXPECT_EQ(refined.cell_edges(), (Vec3d{0.05, 0.025, 0.01}));
  EXPECT_EQ(parse_deck(kMinimalDeck, "<d>", ".", {"domain.voxel_size=.2"}).spacing,
            (Vec3d{0.2, 0.2, 0.2}));
  // [[point_mass]] and its alias, and a pre-load released at t = 0.
  const Config c = parse_deck(kMinimalDeck + R"(
[[point_mass]]
lo = [0, 0, 0.4]
hi = [0.1, 0.1, 0.5]
mass = 0.005
[[attached_mass]]
lo = [0, 0, -0.5]
hi = [0.1, 0.1, -0.4]
mass = 2
[[force]]
lo = [0, 0, 0.4]
hi = [1, 1, 1]
force = [0, 0, 1.2]
start = -1
end = 0
)",
                              "<d>", ".", {});
  ASSERT_EQ(c.point_masses.size(), 2u);
  EXPECT_EQ(c.point_masses[0].mass, 0.005);
  EXPECT_EQ(c.point_masses[1].mass, 2.0);
  EXPECT_NE(c.point_masses[0].where.find("<d>:"), std::string::npos);
  ASSERT_EQ(c.forces.size(), 1u);
  EXPECT_EQ(c.forces[0].start, -1.0);
  struct Case {
    std::string extra, needle;
  };
  const std::vector<Case> cases = {
      {"\n[[point_mass]]\nlo = [0, 0, 0]\nhi = [1, 1, 1]\nmass = 0\n", "point_mass.0.mass"},
      {"\n[[point_mass]]\nlo = [0, 0, 0]\nhi = [1, 1, 1]\n", "point_mass.0.mass"},
      {"\n[[point_mass]]\nlo = [0, 0, 0]\nhi = [1, 1, 1]\nmass = 1\nforce = [0, 0, 1]\n", "force"},
      {"\n[[force]]\nlo = [0, 0, 0]\nhi = [1, 1, 1]\nforce = [0, 0, 1]\nstart = -1\nend = -0.5\n",
       "released at end >= 0"},
  };
  for (const Case& k : cases) {
    const std::string msg = load_error("pm_error.toml", kMinimalDeck + k.extra);
    EXPECT_NE(msg.find(k.needle), std::string::npos) << k.extra << " -> " << msg;
    EXPECT_NE(msg.find("pm_error.toml:"), std::string::npos) << msg;
  }
  const std::string box_msg =
      load_error("box_error.toml",
                 replace_line(kMinimalDeck, "voxel_size = 0.1", "voxel_size = [0.1, -0.1, 0.1]"));
  EXPECT_NE(box_msg.find("domain.voxel_size"), std::string::npos) << box_msg;
  // The MPM grid takes cubes only.
  const std::string mpm_msg = load_error(
      "mpm_box.toml",
      replace_line(replace_line(kMinimalDeck, "voxel_size = 0.1", "voxel_size = [0.1, 0.1, 0.05]"),
                   "density = 500", "density = 500\nmodel = \"fixed_corotated\"") +
          "\n[solver]\nmethod = \"mpm\"\n");
  EXPECT_NE(mpm_msg.find("cubic cells"), std::string::npos) << mpm_msg;
}

TEST(DeckDocs, ReadmeDocumentsEveryKey) {
  const std::string readme = read_readme();
  ASSERT_FALSE(readme.empty());
  for (const auto& table : deck::schema()) {
    const std::string name(table.name);
    if (name == "attached_mass") continue;  // [[point_mass]]'s alias, in its section
    const std::string header = table.is_array ? "`[[" + name + "]]`" : "`[" + name + "]`";
    EXPECT_NE(readme.find("## " + header), std::string::npos) << header;
    // Each key has a row in its table's section (sections run from one "## " to the next).
    const auto begin = readme.find("## " + header);
    const auto end = readme.find("\n## ", begin + 1);
    const std::string section = readme.substr(begin, end - begin);
    for (const auto& key : table.keys)
      EXPECT_NE(section.find("\n| `" + std::string(key.name) + "` |"), std::string::npos)
          << name << "." << key.name;
  }
}

TEST(DeckDocs, ReadmeMinimalDeckIsValid) {
  const std::string readme = read_readme();
  const auto begin = readme.find("```toml\n");
  ASSERT_NE(begin, std::string::npos);
  const auto end = readme.find("```", begin + 8);
  const Config c = parse_deck(readme.substr(begin + 8, end - begin - 8), "README minimal", ".");
  EXPECT_EQ(c.geometry.size(), 1u);
  EXPECT_EQ(c.fixed.size(), 1u);
}

TEST(DeckDocs, ShippedDecksAreValid) {
  int decks = 0;
  for (const auto& entry : fs::directory_iterator(fs::path(GEN4D_SOURCE_DIR) / "inputs")) {
    if (entry.path().extension() != ".toml") continue;
    ++decks;
    EXPECT_NO_THROW(load_deck(entry.path().string(), {})) << entry.path();
  }
  if (decks == 0) GTEST_SKIP() << "no decks in inputs/";
}

}  // namespace
}  // namespace gen4d::test
