// PhysGaussian JSON configs: reading (values, defaults, errors), preprocessing and conversion to
// gen4d decks.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/Config.hpp"
#include "core/Deck.hpp"
#include "core/Error.hpp"
#include "gaussians/Camera.hpp"
#include "gaussians/DeckSplats.hpp"
#include "gaussians/PhysGaussianConfig.hpp"
#include "gaussians/PhysGaussianOutput.hpp"
#include "gaussians/Ply.hpp"

namespace fs = std::filesystem;
using namespace gen4d::gaussians;
using gen4d::InputError;

namespace {

std::string fixture(const std::string& name) {
  return (fs::path(GEN4D_SOURCE_DIR) / "tests" / "data" / "physgaussian" / name).string();
}

//! A scratch folder removed at the end of the test.
class TempDir {
 public:
  TempDir() {
    path_ = fs::temp_directory_path() /
            ("gen4d_pgcfg_" + std::to_string(::getpid()) + "_" + std::to_string(counter_++));
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  std::string write(const std::string& name, const std::string& text) const {
    const fs::path p = path_ / name;
    std::ofstream(p) << text;
    return p.string();
  }
  std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  fs::path path_;
  static inline int counter_ = 0;
};

//! The InputError message of reading `text` as a config (empty when it reads).
std::string read_error(const TempDir& dir, const std::string& text) {
  const std::string path = dir.write("cfg.json", text);
  try {
    read_physgaussian_config(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

//! Isotropic splats (sigma 0.05, opacity 0.9, grey, SH degree 0) at the given positions.
SplatSet splats_at(const std::vector<PgVec3>& points) {
  SplatSet s;
  s.sh_degree = 0;
  for (const PgVec3& p : points) {
    s.position.insert(s.position.end(), p.begin(), p.end());
    s.scale.insert(s.scale.end(), {0.05, 0.05, 0.05});
    s.rotation.insert(s.rotation.end(), {1, 0, 0, 0});
    s.opacity.push_back(0.9);
    s.sh.insert(s.sh.end(), {0.1, 0.2, 0.3});
  }
  return s;
}

//! A lattice of n^3 points over [lo, hi]^3.
std::vector<PgVec3> lattice(double lo, double hi, int n) {
  std::vector<PgVec3> pts;
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const double h = (hi - lo) / (n - 1);
        pts.push_back({lo + i * h, lo + j * h + 0.013 * i, lo + k * h - 0.007 * j});
      }
  return pts;
}

void expect_vec(const PgVec3& got, const PgVec3& want, double tol = 0) {
  for (int d = 0; d < 3; ++d) EXPECT_NEAR(got[d], want[d], tol) << "component " << d;
}

//! A trained object as it is stored: `trained` written to dir/object.ply (float32), and what
//! preprocessing under p makes of the file read back.
struct StoredObject {
  std::string ply;
  PhysGaussianPreprocessed pre;
};
StoredObject store_and_preprocess(const TempDir& dir, const SplatSet& trained,
                                  const PhysGaussianParams& p) {
  const std::string ply = dir.file("object.ply");
  write_splats_ply(ply, trained);
  return {ply, preprocess_physgaussian(read_splats_ply(ply), p)};
}

//! The deck physgaussian_to_deck writes for `ply` (trained space) and `pre`, parsed; the
//! conversion's notes in `notes`.
gen4d::Config converted(const TempDir& dir, const PhysGaussianParams& p, const std::string& ply,
                        const PhysGaussianPreprocessed& pre, std::vector<std::string>& notes) {
  return gen4d::parse_deck(physgaussian_to_deck(p, ply, pre, PlySpace::Trained, &notes),
                           "converted.toml", dir.file(""));
}

PgVec3 unit(const PgVec3& v) {
  const double n = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  return {v[0] / n, v[1] / n, v[2] / n};
}
double dot(const PgVec3& a, const PgVec3& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
PgVec3 cross(const PgVec3& a, const PgVec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

}  // namespace

// ---- reading ----

TEST(PhysGaussianConfig, JellyWithCuboidAndBoundingBox) {
  const PhysGaussianParams p = read_physgaussian_config(fixture("jelly_cuboid.json"));
  EXPECT_EQ(p.material, "jelly");
  EXPECT_EQ(p.E, 2e6);
  EXPECT_EQ(p.nu, 0.4);
  EXPECT_EQ(p.density, 200);
  EXPECT_TRUE(p.has_g);
  expect_vec(p.g, {0, 0, 0});
  EXPECT_EQ(p.grid_v_damping_scale, 0.9999);
  EXPECT_EQ(p.substep_dt, 1e-4);
  EXPECT_EQ(p.frame_dt, 4e-2);
  EXPECT_EQ(p.frame_num, 125);
  EXPECT_EQ(p.grid_lim, 2.0);  // defaults
  EXPECT_EQ(p.n_grid, 50);
  EXPECT_EQ(p.scale, 1.0);
  EXPECT_FALSE(p.sim_area.has_value());
  ASSERT_EQ(p.rotation_degree.size(), 1u);
  EXPECT_EQ(p.rotation_axis[0], 0);
  ASSERT_EQ(p.boundary_conditions.size(), 3u);
  EXPECT_EQ(p.boundary_conditions[0].type, "bounding_box");
  const PhysGaussianBoundary& c = p.boundary_conditions[1];
  EXPECT_EQ(c.type, "cuboid");
  EXPECT_EQ(c.line, 19);
  expect_vec(c.point, {1, 1, 0.5});
  expect_vec(c.size, {0.5, 0.5, 0.28});
  expect_vec(c.velocity, {0, 0, 0});
  EXPECT_EQ(c.end_time, 1e3);
  EXPECT_EQ(c.reset, 1);
  const PhysGaussianBoundary& imp = p.boundary_conditions[2];
  EXPECT_EQ(imp.type, "particle_impulse");
  expect_vec(imp.force, {-0.18, 0, 0});
  EXPECT_EQ(imp.num_dt, 1);
  expect_vec(imp.point, {1, 1, 1});  // PhysGaussian's defaults for the impulse box
  expect_vec(imp.size, {1, 1, 1});
  ASSERT_EQ(p.additional_material_params.size(), 1u);
  EXPECT_EQ(p.additional_material_params[0].density, 70);
  expect_vec(p.additional_material_params[0].size, {1.0, 1.0, 0.5});
  expect_vec(p.mpm_space_viewpoint_center, {0.95, 1.07, 1});
  EXPECT_EQ(p.default_camera_index, -1);
  EXPECT_EQ(*p.init_azimuthm, -36.7);
  EXPECT_EQ(*p.init_elevation, 8.96);
  EXPECT_EQ(*p.init_radius, 4.11);
  EXPECT_TRUE(p.move_camera);
  EXPECT_EQ(*p.delta_a, 0.4);
}

TEST(PhysGaussianConfig, SandWithSurfaceCollider) {
  const PhysGaussianParams p = read_physgaussian_config(fixture("sand_collider.json"));
  EXPECT_EQ(p.material, "sand");
  EXPECT_EQ(p.friction_angle, 30);
  EXPECT_EQ(p.n_grid, 200);
  ASSERT_TRUE(p.particle_filling.has_value());
  const PhysGaussianFilling& f = *p.particle_filling;
  EXPECT_EQ(f.n_grid, 100);
  EXPECT_EQ(f.density_threshold, 100.0);
  EXPECT_EQ(f.search_threshold, 1.0);
  EXPECT_EQ(f.search_exclude_direction, 2);
  EXPECT_EQ(f.max_particles_per_cell, 3);  // from PhysGaussian's spelling
  ASSERT_TRUE(f.boundary.has_value());
  EXPECT_EQ((*f.boundary)[5], 1.6);
  EXPECT_TRUE(f.smooth);
  EXPECT_TRUE(f.visualize);
  const PhysGaussianBoundary& s = p.boundary_conditions[1];
  EXPECT_EQ(s.type, "surface_collider");
  expect_vec(s.point, {1, 1, 0.48});
  expect_vec(s.normal, {0, 0, 2});
  EXPECT_EQ(s.surface, "sticky");
  EXPECT_EQ(s.friction, 0);
  const PhysGaussianBoundary& r = p.boundary_conditions[2];
  EXPECT_EQ(r.type, "release_particles_sequentially");
  EXPECT_EQ(r.start_position, 1.5);
  EXPECT_EQ(r.end_position, 0.5);
  EXPECT_EQ(r.num_layers, 50);
  EXPECT_EQ(r.end_time, 1.5);
}

TEST(PhysGaussianConfig, MetalWithVelocityRotation) {
  const PhysGaussianParams p = read_physgaussian_config(fixture("metal_rotation.json"));
  EXPECT_EQ(p.material, "metal");
  EXPECT_TRUE(p.has_yield_stress);
  EXPECT_EQ(p.yield_stress, 100);
  EXPECT_EQ(p.hardening, 1);
  EXPECT_EQ(p.xi, 0.5);
  EXPECT_EQ(p.rotation_degree, (std::vector<double>{45.0, 6.5}));
  EXPECT_EQ(p.rotation_axis, (std::vector<int>{1, 2}));
  ASSERT_TRUE(p.sim_area.has_value());
  EXPECT_EQ((*p.sim_area)[0], -2.1);
  EXPECT_EQ((*p.sim_area)[3], 0.9);
  EXPECT_FALSE(p.particle_filling.has_value());
  ASSERT_EQ(p.boundary_conditions.size(), 3u);
  const PhysGaussianBoundary& b = p.boundary_conditions[1];
  EXPECT_EQ(b.type, "enforce_particle_velocity_rotation");
  expect_vec(b.point, {0.7, 1.03, 0.98});
  expect_vec(b.normal, {2, 0, 0});
  EXPECT_EQ(b.half_height_and_radius[0], 0.12);
  EXPECT_EQ(b.half_height_and_radius[1], 0.6);
  EXPECT_EQ(b.rotation_scale, 1.0);
  EXPECT_EQ(b.translation_scale, 0.25);
  EXPECT_EQ(b.end_time, 0.5);
  expect_vec(p.mpm_space_vertical_upward_axis, {0, -1, 0});
}

TEST(PhysGaussianConfig, DefaultsWhenKeysAreAbsent) {
  TempDir dir;
  const PhysGaussianParams p = read_physgaussian_config(dir.write("empty.json", "{}"));
  EXPECT_EQ(p.material, "jelly");
  EXPECT_EQ(p.grid_lim, 2.0);
  EXPECT_EQ(p.n_grid, 50);
  EXPECT_EQ(p.E, 1e5);
  EXPECT_EQ(p.nu, 0.4);
  EXPECT_EQ(p.density, 200.0);
  EXPECT_FALSE(p.has_g);
  expect_vec(p.g, {0, 0, -9.8});
  EXPECT_EQ(p.yield_stress, 0);
  EXPECT_EQ(p.hardening, 0);
  EXPECT_EQ(p.friction_angle, 25.0);
  EXPECT_EQ(p.softening, 0.1);
  EXPECT_EQ(p.grid_v_damping_scale, 1.1);
  EXPECT_EQ(p.substep_dt, 1e-4);
  EXPECT_EQ(p.frame_dt, 1e-2);
  EXPECT_EQ(p.frame_num, 100);
  EXPECT_EQ(p.opacity_threshold, 0.02);
  EXPECT_TRUE(p.rotation_degree.empty());
  EXPECT_FALSE(p.sim_area.has_value());
  EXPECT_EQ(p.scale, 1.0);
  EXPECT_FALSE(p.particle_filling.has_value());
  EXPECT_TRUE(p.boundary_conditions.empty());
  expect_vec(p.mpm_space_viewpoint_center, {1, 1, 1});
  expect_vec(p.mpm_space_vertical_upward_axis, {0, 0, 1});
  EXPECT_EQ(p.default_camera_index, 0);
  EXPECT_FALSE(p.show_hint);
  EXPECT_FALSE(p.init_azimuthm.has_value());
  EXPECT_FALSE(p.move_camera);

  // Nested defaults: filling's n_grid is 4 n_grid; a box's density is the global one;
  // null stands for PhysGaussian's None.
  const PhysGaussianParams q = read_physgaussian_config(
      dir.write("nested.json",
                R"({"n_grid": 30, "density": 500, "particle_filling": {"boundary": null},
          "additional_material_params": [{"point": [1, 1, 1], "size": [1, 1, 1], "E": 3,
                                          "nu": 0.2}],
          "sim_area": null, "init_radius": null,
          "boundary_conditions": [{"type": "cuboid", "point": [1, 1, 1], "size": [1, 1, 1],
                                   "velocity": [0, 0, 1]}]})"));
  ASSERT_TRUE(q.particle_filling.has_value());
  EXPECT_EQ(q.particle_filling->n_grid, 120);
  EXPECT_EQ(q.particle_filling->density_threshold, 5.0);
  EXPECT_EQ(q.particle_filling->search_threshold, 3.0);
  EXPECT_EQ(q.particle_filling->max_particles_num, 2000000);
  EXPECT_EQ(q.particle_filling->max_particles_per_cell, 1);
  EXPECT_EQ(q.particle_filling->search_exclude_direction, 5);
  EXPECT_EQ(q.particle_filling->ray_cast_direction, 4);
  EXPECT_FALSE(q.particle_filling->boundary.has_value());
  EXPECT_FALSE(q.particle_filling->smooth);
  EXPECT_EQ(q.additional_material_params[0].density, 500);
  EXPECT_FALSE(q.sim_area.has_value());
  EXPECT_FALSE(q.init_radius.has_value());
  EXPECT_EQ(q.boundary_conditions[0].start_time, 0);
  EXPECT_EQ(q.boundary_conditions[0].end_time, 1e3);
  EXPECT_EQ(q.boundary_conditions[0].reset, 0);
}

TEST(PhysGaussianConfig, BothSpellingsOfMaxParticlesPerCell) {
  TempDir dir;
  const PhysGaussianParams a = read_physgaussian_config(
      dir.write("a.json", R"({"particle_filling": {"max_partciels_per_cell": 4}})"));
  EXPECT_EQ(a.particle_filling->max_particles_per_cell, 4);
  const PhysGaussianParams b = read_physgaussian_config(
      dir.write("b.json", R"({"particle_filling": {"max_particles_per_cell": 2}})"));
  EXPECT_EQ(b.particle_filling->max_particles_per_cell, 2);
  const std::string e = read_error(
      dir,
      "{\"particle_filling\": {\"max_partciels_per_cell\": 4,\n\"max_particles_per_cell\": 4}}");
  EXPECT_NE(e.find("cfg.json:2: key 'particle_filling.max_particles_per_cell'"), std::string::npos)
      << e;
}

TEST(PhysGaussianConfig, ErrorsNameFileLineAndKey) {
  TempDir dir;
  struct Case {
    std::string text, expected;
  };
  const std::vector<Case> cases = {
      {"{\n  \"E\": 1e5,\n  \"youngs\": 3\n}", "cfg.json:3: key 'youngs': unknown key"},
      {"{\n  \"E\": \"big\"\n}", "cfg.json:2: key 'E': expected a number, got string"},
      {"{\"boundary_conditions\": [\n {\"type\": \"bounding_box\"},\n {\"type\": \"cuboid\",\n"
       "  \"point\": [1, 1, 1], \"size\": [1, 1, 1],\n  \"velocity\": [0, 0]}]}",
       "cfg.json:5: key 'boundary_conditions[1].velocity': expected an array of 3 numbers"},
      {"{\"boundary_conditions\": [\n {\"type\": \"cuboid\",\n  \"point\": [1, 1, 1], \"size\": "
       "[1, 1, 1],\n  \"velocity\": [0, \"a\", 0]}]}",
       "cfg.json:4: key 'boundary_conditions[0].velocity': expected an array of 3 numbers"},
      {"{\"boundary_conditions\": [\n {\"type\": \"bounding_box\",\n  \"point\": [1, 1, 1]}]}",
       "cfg.json:3: key 'boundary_conditions[0].point': unknown key for type 'bounding_box'"},
      {"{\"boundary_conditions\": [\n {\"type\": \"surface_collider\", \"point\": [1, 1, 1],\n"
       "  \"normal\": [0, 0, 1], \"surface\": \"sticky\", \"friction\": 0.0}]}",
       "cfg.json:2: key 'boundary_conditions[0].start_time': is required"},
      {"{\"boundary_conditions\": [\n {\"type\": \"teleport\"}]}",
       "cfg.json:2: key 'boundary_conditions[0].type': unknown boundary condition type"},
      {"{\"boundary_conditions\": [{\"type\": \"surface_collider\", \"point\": [1, 1, 1],\n"
       "  \"normal\": [0, 0, 1], \"surface\": \"sticky\",\n  \"friction\": 0.3, \"start_time\": 0, "
       "\"end_time\": 1}]}",
       "cfg.json:3: key 'boundary_conditions[0].friction': must be 0 on a sticky surface"},
      {"{\n\"nu\": 0.6}", "cfg.json:2: key 'nu': must be in [0, 0.5]"},
      {"{\n\"material\": \"rubber\"}", "cfg.json:2: key 'material': unknown material 'rubber'"},
      {"{\"rotation_degree\": [90, 0],\n\"rotation_axis\": [0]}",
       "cfg.json:2: key 'rotation_axis': has 1 entries but rotation_degree has 2"},
      {"{\"rotation_degree\": [90],\n\"rotation_axis\": [3]}",
       "cfg.json:2: key 'rotation_axis': axis must be 0, 1 or 2"},
      {"{\n\"sim_area\": [0, 1, 0, 1]}", "cfg.json:2: key 'sim_area': expected an array of 6"},
      {"{\n\"n_grid\": 12.5}", "cfg.json:2: key 'n_grid': expected an integer"},
      {"{\"default_camera_index\": -1,\n\"init_azimuthm\": 0, \"init_elevation\": 0}",
       "cfg.json:1: key 'init_radius': is required by the orbit camera"},
      {"{\"g\": 9.8}", "cfg.json:1: key 'g': expected an array of 3 numbers"},
      {"{\"additional_material_params\": [\n{\"point\": [1, 1, 1], \"size\": [1, 1, 1], \"E\": 1,"
       "\n\"nu\": 0.3, \"yield_stress\": 4}]}",
       "cfg.json:3: key 'additional_material_params[0].yield_stress': unknown key"},
  };
  for (const Case& c : cases) {
    const std::string e = read_error(dir, c.text);
    EXPECT_NE(e.find(c.expected), std::string::npos) << "got: " << e << "\nfor: " << c.text;
    EXPECT_NE(e.find(dir.file("cfg.json")), std::string::npos) << e;
  }
  // Malformed JSON: the strict reader's file:line message.
  const std::string bad = read_error(dir, "{\n  \"E\": 1e5,\n}");
  EXPECT_NE(bad.find(dir.file("cfg.json") + ":3"), std::string::npos) << bad;
  const std::string missing = [&] {
    try {
      read_physgaussian_config(dir.file("none.json"));
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  }();
  EXPECT_NE(missing.find("none.json"), std::string::npos) << missing;
}

// ---- preprocessing ----

TEST(PhysGaussianPreprocess, RotationsApplyInListOrder) {
  PhysGaussianParams p;
  p.rotation_degree = {90, 90};
  p.rotation_axis = {0, 2};  // first about x, then about z
  const auto R = physgaussian_rotation(p);
  auto apply = [&](PgVec3 v) {
    return PgVec3{R[0] * v[0] + R[1] * v[1] + R[2] * v[2], R[3] * v[0] + R[4] * v[1] + R[5] * v[2],
                  R[6] * v[0] + R[7] * v[1] + R[8] * v[2]};
  };
  expect_vec(apply({0, 0, 1}), {1, 0, 0}, 1e-15);  // x: (0,0,1) -> (0,-1,0); z: -> (1,0,0)
  expect_vec(apply({0, 1, 0}), {0, 0, 1}, 1e-15);
}

TEST(PhysGaussianPreprocess, KnownSetToSimulationSpaceAndBack) {
  // A (0,0,0), B (2,0,0), C (0,1,0); D is below the opacity threshold; E lies outside sim_area
  // after the rotation by 90 degrees about z, (x, y, z) -> (-y, x, z).
  SplatSet s = splats_at({{0, 0, 0}, {2, 0, 0}, {0, 1, 0}, {5, 5, 5}, {0, 0, 10}});
  s.opacity[3] = 0.01;
  PhysGaussianParams p;
  p.opacity_threshold = 0.02;
  p.rotation_degree = {90};
  p.rotation_axis = {2};
  p.sim_area = std::array<double, 6>{-5, 5, -5, 5, -5, 5};
  p.scale = 1.0;
  const PhysGaussianPreprocessed pre = preprocess_physgaussian(s, p);
  EXPECT_EQ(pre.selected_index, (std::vector<std::size_t>{0, 1, 2}));
  EXPECT_EQ(pre.rest_index, (std::vector<std::size_t>{4}));
  // Rotated selection: (0,0,0), (0,2,0), (-1,0,0): box centre (-0.5, 1, 0), longest side 2.
  EXPECT_DOUBLE_EQ(pre.map.scale, 0.5);
  expect_vec(pre.map.center, {-0.5, 1, 0}, 1e-15);
  ASSERT_EQ(pre.selected.size(), 3u);
  const PgVec3 want[] = {{1.25, 0.5, 1}, {1.25, 1.5, 1}, {0.75, 0.5, 1}};
  for (int i = 0; i < 3; ++i)
    expect_vec({pre.selected.position[3 * i], pre.selected.position[3 * i + 1],
                pre.selected.position[3 * i + 2]},
               want[i], 1e-15);
  ASSERT_EQ(pre.rest.size(), 1u);
  expect_vec({pre.rest.position[0], pre.rest.position[1], pre.rest.position[2]}, {1.25, 0.5, 6},
             1e-14);
  // Covariances scale by s^2 (sigma 0.05 -> 0.025) and orientations turn with R.
  EXPECT_NEAR(pre.selected.scale[0], 0.025, 1e-16);
  const auto cov = pre.selected.covariance(0);
  EXPECT_NEAR(cov[0], 0.025 * 0.025, 1e-18);
  EXPECT_NEAR(cov[1], 0.0, 1e-18);
  EXPECT_NEAR(pre.selected.rotation[0], std::sqrt(0.5), 1e-15);
  EXPECT_NEAR(pre.selected.rotation[3], std::sqrt(0.5), 1e-15);
  // The map both ways.
  for (const PgVec3& w : std::vector<PgVec3>{{0, 0, 0}, {2, 0, 0}, {0.3, -4, 7}}) {
    expect_vec(pre.map.to_world(pre.map.to_sim(w)), w, 1e-14);
  }
  expect_vec(pre.map.to_sim({2, 0, 0}), {1.25, 1.5, 1}, 1e-15);
  expect_vec(pre.map.to_world({0.75, 0.5, 1}), {0, 1, 0}, 1e-15);
  // scale = 0.6 makes the longest side 0.6.
  p.scale = 0.6;
  EXPECT_DOUBLE_EQ(preprocess_physgaussian(s, p).map.scale, 0.3);
}

TEST(PhysGaussianPreprocess, NothingSelectedIsAnInputError) {
  SplatSet s = splats_at({{0, 0, 0}, {1, 0, 0}});
  PhysGaussianParams p;
  p.source = "scene.json";
  p.sim_area = std::array<double, 6>{5, 6, 5, 6, 5, 6};
  EXPECT_THROW(preprocess_physgaussian(s, p), InputError);
  p.sim_area.reset();
  s.opacity = {0.01, 0.015};
  try {
    preprocess_physgaussian(s, p);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("scene.json"), std::string::npos);
  }
  // A single point has no extent for `scale`.
  EXPECT_THROW(preprocess_physgaussian(splats_at({{1, 2, 3}}), p), InputError);
}

// ---- conversion ----

TEST(PhysGaussianDeck, JellyDeckParsesToTheSameScene) {
  TempDir dir;
  const PhysGaussianParams p = read_physgaussian_config(fixture("jelly_cuboid.json"));
  const SplatSet trained = splats_at(lattice(-0.8, 0.6, 6));
  const auto [ply, pre] = store_and_preprocess(dir, trained, p);
  std::vector<std::string> notes;
  const gen4d::Config c = converted(dir, p, ply, pre, notes);
  EXPECT_EQ(c.solver.method, "mpm");
  EXPECT_EQ(c.dt, 1e-4);
  EXPECT_DOUBLE_EQ(c.end_time, 4e-2 * 125);
  EXPECT_EQ(c.output.frame_interval, 4e-2);
  expect_vec(c.gravity, {0, 0, 0});
  EXPECT_DOUBLE_EQ(c.voxel_size, 2.0 / 50);
  EXPECT_TRUE(c.mpm.has_box);
  expect_vec(c.mpm.lo, {0, 0, 0});
  expect_vec(c.mpm.hi, {2, 2, 2});
  EXPECT_EQ(c.mpm.substep, "fixed");
  EXPECT_EQ(c.mpm.boundary_layers, 3);
  EXPECT_EQ(c.material.model, "fixed_corotated");
  EXPECT_EQ(c.material.youngs_modulus, 2e6);
  EXPECT_EQ(c.material.poisson_ratio, 0.4);
  EXPECT_EQ(c.material.density, 200);
  EXPECT_TRUE(c.material.params.empty());
  // additional_material_params: the same model with the box's constants, bound to its box.
  ASSERT_EQ(c.material_regions.size(), 1u);
  const gen4d::MaterialConfig& box = c.material_regions[0];
  EXPECT_EQ(box.model, "fixed_corotated");
  EXPECT_EQ(box.density, 70);
  EXPECT_TRUE(box.has_region);
  expect_vec(box.region.lo, {0.0, 0.0, 1.0});
  expect_vec(box.region.hi, {2.0, 2.0, 2.0});
  ASSERT_EQ(c.boundaries.size(), 3u);
  EXPECT_EQ(c.boundaries[0].type, "bounding_box");
  const gen4d::BoundaryConfig& cub = c.boundaries[1];
  EXPECT_EQ(cub.type, "cuboid");
  expect_vec(cub.region.lo, {0.5, 0.5, 0.22}, 1e-15);
  expect_vec(cub.region.hi, {1.5, 1.5, 0.78}, 1e-15);
  EXPECT_EQ(cub.end, 1e3);
  const gen4d::BoundaryConfig& imp = c.boundaries[2];
  EXPECT_EQ(imp.type, "particle_impulse");
  expect_vec(imp.region.lo, {0, 0, 0});
  expect_vec(imp.region.hi, {2, 2, 2});
  EXPECT_EQ(imp.start, 0);
  EXPECT_DOUBLE_EQ(imp.end, 1e-4);
  // Every Gaussian lies in the default impulse box [0, 2]^3: total = per-particle force x N.
  EXPECT_DOUBLE_EQ(imp.force[0], -0.18 * static_cast<double>(pre.selected.size()));
  // The geometry places the trained file exactly where the preprocessing does.
  ASSERT_EQ(c.geometry.size(), 1u);
  const SplatSet placed = load_geometry_splats(c.geometry[0]);
  ASSERT_EQ(placed.size(), pre.selected.size());
  for (std::size_t i = 0; i < placed.position.size(); ++i)
    EXPECT_NEAR(placed.position[i], pre.selected.position[i], 1e-12) << i;
  // Notes name what gen4d does not honour.
  auto has_note = [&](const std::string& what) {
    for (const std::string& n : notes)
      if (n.find(what) != std::string::npos) return true;
    return false;
  };
  EXPECT_TRUE(has_note("additional_material_params"));
  EXPECT_FALSE(has_note("reset = 1"));  // honoured; start_time 0: no difference
  EXPECT_FALSE(has_note("grid_v_damping_scale"));
  EXPECT_FALSE(has_note("substeps per frame"));  // 0.04 / 1e-4 is exactly 400
  EXPECT_FALSE(has_note("rpic_damping"));        // 0: nothing to report
  // reset = 1: the grid zeroed for 15 substeps; the still cuboid stays fixed.
  EXPECT_EQ(cub.motion, "fixed");
  EXPECT_DOUBLE_EQ(cub.reset_duration, 15 * 1e-4);
  EXPECT_EQ(c.mpm.grid_velocity_scale, 0.9999);
  EXPECT_EQ(c.mpm.rpic_damping, 0);
}

TEST(PhysGaussianDeck, DampingMovingCuboidAndCutReachTheDeck) {
  TempDir dir;
  PhysGaussianParams p = read_physgaussian_config(fixture("jelly_cuboid.json"));
  const SplatSet trained = splats_at(lattice(-0.8, 0.6, 6));
  const auto [ply, pre] = store_and_preprocess(dir, trained, p);
  p.rpic_damping = -1;
  p.grid_v_damping_scale = 0.9995;
  PhysGaussianBoundary& cub = p.boundary_conditions[1];
  cub.velocity = {0, 0, 0.2};
  cub.start_time = 0.1;
  cub.end_time = 0.6;
  PhysGaussianBoundary cut;
  cut.type = "surface_collider";
  cut.point = {1, 0.8, 1};
  cut.normal = {0, 2, 0};
  cut.surface = "cut";
  cut.end_time = 5;
  p.boundary_conditions.push_back(cut);
  std::vector<std::string> notes;
  const gen4d::Config c = converted(dir, p, ply, pre, notes);
  EXPECT_EQ(c.mpm.rpic_damping, -1);  // below -0.001: PIC
  EXPECT_EQ(c.mpm.grid_velocity_scale, 0.9995);
  ASSERT_EQ(c.boundaries.size(), 4u);
  const gen4d::BoundaryConfig& b = c.boundaries[1];
  EXPECT_EQ(b.motion, "moving");
  expect_vec(b.velocity, {0, 0, 0.2});
  EXPECT_EQ(b.start, 0.1);
  EXPECT_EQ(b.end, 0.6);
  EXPECT_DOUBLE_EQ(b.reset_duration, 15 * 1e-4);
  const gen4d::BoundaryConfig& k = c.boundaries[3];
  EXPECT_EQ(k.surface, "cut");
  expect_vec(k.normal, {0, 1, 0});
  expect_vec(k.region.lo, {0, 0, 0.4});
  expect_vec(k.region.hi, {2, 2, 0.53});
  EXPECT_EQ(k.cut_scale, 0.3);
  auto has_note = [&](const std::string& what) {
    for (const std::string& n : notes)
      if (n.find(what) != std::string::npos) return true;
    return false;
  };
  EXPECT_TRUE(has_note("also zeroes it before start_time"));  // start_time 0.1 > 0
  EXPECT_FALSE(has_note("PhysGaussian the y component"));     // the normal is y
  EXPECT_FALSE(has_note("rpic_damping"));
  EXPECT_FALSE(has_note("stays put"));
  // A cut whose normal is not y, and an rpic_damping PhysGaussian extrapolates, are noted.
  p.boundary_conditions[3].normal = {0, 0, 1};
  p.rpic_damping = 1.5;
  p.grid_v_damping_scale = 1.1;
  notes.clear();
  const gen4d::Config d = converted(dir, p, ply, pre, notes);
  EXPECT_TRUE(has_note("PhysGaussian the y component"));
  EXPECT_TRUE(has_note("rpic_damping = 1.5: not honoured"));
  EXPECT_EQ(d.mpm.rpic_damping, 0);
  EXPECT_EQ(d.mpm.grid_velocity_scale, 1);  // 1.1: PhysGaussian's "off"
}

TEST(PhysGaussianDeck, OrbitCameraMatchesPhysGaussiansViews) {
  TempDir dir;
  const PhysGaussianParams p = read_physgaussian_config(fixture("metal_rotation.json"));
  const SplatSet trained = splats_at(lattice(-3, 3, 9));
  const PhysGaussianPreprocessed pre = preprocess_physgaussian(trained, p);
  const std::string ply = dir.file("selected.ply");
  write_splats_ply(ply, pre.selected);
  const gen4d::Config c = gen4d::parse_deck(physgaussian_to_deck(p, ply, pre, PlySpace::Simulation),
                                            "converted.toml", dir.file(""));
  ASSERT_EQ(c.render.camera, "orbit");
  OrbitCamera orbit;
  orbit.center = c.render.center;
  orbit.up = c.render.up;
  orbit.azimuth = c.render.azimuth;
  orbit.elevation = c.render.elevation;
  orbit.radius = c.render.radius;
  orbit.d_azimuth = c.render.d_azimuth;
  orbit.d_elevation = c.render.d_elevation;
  orbit.d_radius = c.render.d_radius;
  // PhysGaussian's camera of frame k (utils/camera_view_utils.py), built in the trained space.
  const auto& M = pre.map;
  const PgVec3 cw = M.to_world(p.mpm_space_viewpoint_center);
  const PgVec3 upw =
      M.to_world({p.mpm_space_viewpoint_center[0] + p.mpm_space_vertical_upward_axis[0],
                  p.mpm_space_viewpoint_center[1] + p.mpm_space_vertical_upward_axis[1],
                  p.mpm_space_viewpoint_center[2] + p.mpm_space_vertical_upward_axis[2]});
  const PgVec3 v = unit({upw[0] - cw[0], upw[1] - cw[1], upw[2] - cw[2]});
  PgVec3 h1{1, 1, 1};
  const double hv = dot(h1, v);
  h1 = unit({h1[0] - hv * v[0], h1[1] - hv * v[1], h1[2] - hv * v[2]});
  const PgVec3 h2 = cross(h1, v);
  const double deg = 3.14159265358979323846 / 180;
  for (int k : {0, 1, 7, 50}) {
    const double a = (*p.init_azimuthm + k * *p.delta_a) * deg;
    const double e = (*p.init_elevation + k * *p.delta_e) * deg;
    const double r = *p.init_radius + k * *p.delta_r;
    PgVec3 pos;
    for (int d = 0; d < 3; ++d)
      pos[d] = cw[d] + r * (std::cos(a) * std::cos(e) * h1[d] + std::sin(a) * std::cos(e) * h2[d] +
                            std::sin(e) * v[d]);
    // PhysGaussian renders the state after k + 1 frames with the view of frame k.
    const Camera cam = orbit.at_frame(k + 1);
    expect_vec(cam.position, M.to_sim(pos), 1e-12);
  }
}

TEST(PhysGaussianDeck, MetalDeckMaterialAndVelocityRotation) {
  TempDir dir;
  const PhysGaussianParams p = read_physgaussian_config(fixture("metal_rotation.json"));
  const PhysGaussianPreprocessed pre = preprocess_physgaussian(splats_at(lattice(-3, 3, 9)), p);
  // The crop: every selected Gaussian lay inside sim_area after the rotation.
  EXPECT_GT(pre.rest.size(), 0u);
  const std::string ply = dir.file("selected.ply");
  write_splats_ply(ply, pre.selected);
  std::vector<std::string> notes;
  const gen4d::Config c =
      gen4d::parse_deck(physgaussian_to_deck(p, ply, pre, PlySpace::Simulation, &notes),
                        "converted.toml", dir.file(""));
  EXPECT_EQ(c.material.model, "von_mises");
  EXPECT_DOUBLE_EQ(c.material.params.at("yield_stress"), std::sqrt(1.5) * 100);
  const double mu = 1e5 / (2 * 1.3);
  EXPECT_DOUBLE_EQ(c.material.params.at("hardening"), 3 * mu * 0.5);
  EXPECT_EQ(c.mpm.boundary_layers, 0);  // no bounding_box entry: no walls
  EXPECT_DOUBLE_EQ(c.voxel_size, 2.0 / 120);
  ASSERT_EQ(c.boundaries.size(), 3u);
  EXPECT_EQ(c.boundaries[0].type, "enforce_particle_translation");
  expect_vec(c.boundaries[0].region.lo, {0.93, 0.75, 0}, 1e-15);
  expect_vec(c.boundaries[0].region.hi, {1.43, 1.25, 1}, 1e-15);
  const gen4d::BoundaryConfig& b = c.boundaries[1];
  EXPECT_EQ(b.type, "enforce_particle_velocity_rotation");
  EXPECT_EQ(b.half_height, 0.12);
  EXPECT_EQ(b.radius, 0.6);
  EXPECT_EQ(b.end, 0.5);
  // gen4d's rigid field v = velocity + w x (x - point) equals PhysGaussian's kernel
  // (mpm_solver_warp.enforce_particle_velocity_rotation) at sample points in the cylinder.
  const PgVec3 n = unit(p.boundary_conditions[1].normal);
  PgVec3 h1{1, 1, 1};
  const double hn = dot(h1, n);
  h1 = unit({h1[0] - hn * n[0], h1[1] - hn * n[1], h1[2] - hn * n[2]});
  const PgVec3 h2 = cross(h1, n);
  for (const PgVec3& x :
       std::vector<PgVec3>{{0.75, 1.2, 0.9}, {0.65, 0.8, 1.3}, {0.7, 1.03, 1.5}}) {
    const PgVec3 off{x[0] - b.point[0], x[1] - b.point[1], x[2] - b.point[2]};
    const double on = dot(off, n);
    const PgVec3 hor{off[0] - on * n[0], off[1] - on * n[1], off[2] - on * n[2]};
    const double hd = std::sqrt(dot(hor, hor));
    double theta = std::acos(dot(off, h1) / hd);
    if (!(dot(off, h2) > 0)) theta = -theta;
    const double s1 = -hd * std::sin(theta) * 1.0, s2 = hd * std::cos(theta) * 1.0;
    PgVec3 want;
    for (int d = 0; d < 3; ++d) want[d] = s1 * h1[d] + s2 * h2[d] + 0.25 * n[d];
    const PgVec3 wxr = cross(b.angular_velocity, off);
    expect_vec({b.velocity[0] + wxr[0], b.velocity[1] + wxr[1], b.velocity[2] + wxr[2]}, want,
               1e-12);
  }
  EXPECT_EQ(c.boundaries[2].start, 1.0);
  expect_vec(c.boundaries[2].angular_velocity, {1, 0, 0});
  // The deck's geometry is the written selection, untransformed.
  const SplatSet placed = load_geometry_splats(c.geometry[0]);
  ASSERT_EQ(placed.size(), pre.selected.size());
  for (std::size_t i = 0; i < placed.position.size(); ++i)
    EXPECT_NEAR(placed.position[i], pre.selected.position[i], 1e-6) << i;  // float32 file
  bool softening_or_crop = false;
  for (const std::string& s : notes) softening_or_crop |= s.find("sim_area") != std::string::npos;
  EXPECT_TRUE(softening_or_crop);
}

TEST(PhysGaussianDeck, SandDeckColliderAndRelease) {
  TempDir dir;
  const PhysGaussianParams p = read_physgaussian_config(fixture("sand_collider.json"));
  const auto [ply, pre] = store_and_preprocess(dir, splats_at(lattice(-1, 1, 5)), p);
  std::vector<std::string> notes;
  const gen4d::Config c = converted(dir, p, ply, pre, notes);
  EXPECT_EQ(c.material.model, "drucker_prager");
  EXPECT_EQ(c.material.params.at("friction_angle"), 30);
  EXPECT_EQ(c.material.params.count("cohesion"), 0u);
  expect_vec(c.gravity, {0, 0, -9.8});
  EXPECT_EQ(c.dt, 2e-5);
  ASSERT_EQ(c.boundaries.size(), 3u);
  const gen4d::BoundaryConfig& s = c.boundaries[1];
  EXPECT_EQ(s.type, "surface_collider");
  expect_vec(s.point, {1, 1, 0.48});
  expect_vec(s.normal, {0, 0, 1});
  EXPECT_EQ(s.surface, "sticky");
  EXPECT_EQ(s.friction, 0);
  const gen4d::BoundaryConfig& r = c.boundaries[2];
  EXPECT_EQ(r.type, "release_particles_sequentially");
  expect_vec(r.normal, {-1, 0, 0});  // from start_position 1.5 towards end_position 0.5
  EXPECT_EQ(r.layers, 50);
  EXPECT_EQ(r.start, 0);
  EXPECT_EQ(r.end, 1.5);
  ASSERT_EQ(c.geometry.size(), 1u);
  EXPECT_NEAR(c.geometry[0].rotate_degrees, 90, 1e-12);
  expect_vec(c.geometry[0].rotate_axis, {1, 0, 0}, 1e-15);
  // particle_filling's n_grid 100 spans grid_lim 2; the object's side (scale) is 1.
  EXPECT_EQ(c.geometry[0].fill_cells, 50);
  bool filling = false, truncation = false;
  for (const std::string& n : notes) {
    filling |= n.find("particle_filling") != std::string::npos;
    // 0.04 / 2e-5 = 1999.9999999999998: PhysGaussian truncates.
    truncation |= n.find(
                      "int(frame_dt / substep_dt) = 1999 substeps per frame, gen4d rounds "
                      "frame_dt / dt to 2000") != std::string::npos;
  }
  EXPECT_TRUE(filling);
  EXPECT_TRUE(truncation);
  // Camera: elevations in (-90, 90) are required by gen4d's orbit.
  PhysGaussianParams q = p;
  q.init_elevation = 95;
  EXPECT_THROW(physgaussian_to_deck(q, ply, pre, PlySpace::Trained), InputError);
}

TEST(PhysGaussianDeck, EveryMaterialMaps) {
  TempDir dir;
  const std::string ply = dir.file("object.ply");
  write_splats_ply(ply, splats_at(lattice(-1, 1, 3)));
  const SplatSet trained = read_splats_ply(ply);
  struct Case {
    std::string material, model;
  };
  for (const Case& m : std::vector<Case>{{"jelly", "fixed_corotated"},
                                         {"metal", "von_mises"},
                                         {"sand", "drucker_prager"},
                                         {"foam", "herschel_bulkley"},
                                         {"plasticine", "von_mises"},
                                         {"snow", "snow"}}) {
    PhysGaussianParams p;
    p.source = "cfg.json";
    p.material = m.material;
    p.yield_stress = 300;
    p.plastic_viscosity = 8;
    const PhysGaussianPreprocessed pre = preprocess_physgaussian(trained, p);
    std::vector<std::string> notes;
    const gen4d::Config c = converted(dir, p, ply, pre, notes);
    EXPECT_EQ(c.material.model, m.model) << m.material;
    if (m.material == "foam") {
      EXPECT_DOUBLE_EQ(c.material.params.at("yield_stress"), 300 / std::sqrt(3.0));
      EXPECT_DOUBLE_EQ(c.material.params.at("consistency"), 4);
      EXPECT_EQ(c.material.params.at("flow_index"), 1);
    }
    bool softening = false;
    for (const std::string& n : notes) softening |= n.find("softening") != std::string::npos;
    EXPECT_EQ(softening, m.material == "plasticine") << m.material;
    // Defaults: g absent and default_camera_index 0 are reported.
    bool g_note = false, camera_note = false;
    for (const std::string& n : notes) {
      g_note |= n.rfind("g: absent", 0) == 0;
      camera_note |= n.find("default_camera_index = 0") != std::string::npos;
    }
    EXPECT_TRUE(g_note);
    EXPECT_TRUE(camera_note);
    expect_vec(c.gravity, {0, 0, -9.8});
    EXPECT_EQ(c.mpm.boundary_layers, 0);
  }
}

TEST(PhysGaussianPreprocess, TrainedDonutFitsTheSimulationBox) {
  const std::string ply =
      (fs::path(GEN4D_SHARED_DIR) / "data" / "splats" / "donut" / "point_cloud.ply").string();
  if (!fs::exists(ply)) GTEST_SKIP() << "no " << ply;
  const SplatSet donut = read_splats_ply(ply);
  PhysGaussianParams p = read_physgaussian_config(fixture("sand_collider.json"));
  p.scale = 0.8;
  const PhysGaussianPreprocessed pre = preprocess_physgaussian(donut, p);
  std::size_t opaque = 0;
  for (double o : donut.opacity) opaque += o > p.opacity_threshold;
  EXPECT_EQ(pre.selected.size(), opaque);
  EXPECT_EQ(pre.rest.size(), 0u);
  PgVec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  for (std::size_t i = 0; i < pre.selected.size(); ++i)
    for (int d = 0; d < 3; ++d) {
      lo[d] = std::min(lo[d], pre.selected.position[3 * i + d]);
      hi[d] = std::max(hi[d], pre.selected.position[3 * i + d]);
    }
  EXPECT_NEAR(std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]}), 0.8, 1e-12);
  for (int d = 0; d < 3; ++d) EXPECT_NEAR(0.5 * (lo[d] + hi[d]), 1.0, 1e-12);
  // Every selected Gaussian maps back to its trained position.
  for (std::size_t k = 0; k < pre.selected.size(); k += 997) {
    const std::size_t i = pre.selected_index[k];
    expect_vec(pre.map.to_world({pre.selected.position[3 * k], pre.selected.position[3 * k + 1],
                                 pre.selected.position[3 * k + 2]}),
               {donut.position[3 * i], donut.position[3 * i + 1], donut.position[3 * i + 2]},
               1e-12);
  }
}

// ---- images, scenery and cameras.json ----

namespace {

//! Pixel offsets from the principal point of world point `q` seen by `c` (x right, y down).
std::array<double, 2> project(const Camera& c, const PgVec3& q) {
  PgVec3 v{0, 0, 0};
  for (int k = 0; k < 3; ++k)
    for (int i = 0; i < 3; ++i) v[k] += c.rotation[3 * i + k] * (q[i] - c.position[i]);
  return {c.fx * v[0] / v[2], c.fy * v[1] / v[2]};
}

}  // namespace

TEST(PhysGaussianDeck, SceneryAndCamerasJsonViews) {
  TempDir dir;
  PhysGaussianParams p = read_physgaussian_config(fixture("metal_rotation.json"));
  const PhysGaussianPreprocessed pre = preprocess_physgaussian(splats_at(lattice(-3, 3, 9)), p);
  ASSERT_GT(pre.rest.size(), 0u);
  write_splats_ply(dir.file("object.ply"), pre.selected);
  write_splats_ply(dir.file("scenery.ply"), pre.rest);
  // Two trained-space views looking along +y (rows of the camera-to-world rotation).
  Camera a;
  a.width = 64;
  a.height = 48;
  a.fx = 50;
  a.fy = 60;
  a.position = {0, -5, 0};
  a.rotation = {1, 0, 0, 0, 0, 1, 0, -1, 0};
  Camera b = a;
  b.width = 80;
  b.height = 60;
  b.fx = b.fy = 70;
  b.position = {0.5, -4, 1};
  PhysGaussianDeckFiles files;
  files.scenery_ply = "scenery.ply";
  files.cameras_json = "sim_cameras.json";
  files.cameras = {a, b};
  write_cameras_json(dir.file("sim_cameras.json"), cameras_to_simulation(files.cameras, pre.map));

  // The orbit takes the first entry's image size and vertical field of view.
  std::vector<std::string> notes;
  auto convert = [&] {
    return gen4d::parse_deck(
        physgaussian_to_deck(p, "object.ply", pre, PlySpace::Simulation, &notes, &files),
        "converted.toml", dir.file(""));
  };
  gen4d::Config c = convert();
  EXPECT_EQ(c.render.layout, "physgaussian");
  EXPECT_EQ(c.render.fps, 100);  // int(1 / frame_dt), frame_dt = 0.01
  EXPECT_EQ(c.render.background, (gen4d::Vec3d{0, 0, 0}));
  EXPECT_EQ(c.render.scenery, fs::path(dir.file("scenery.ply")).lexically_normal().string());
  EXPECT_EQ(c.render.camera, "orbit");
  EXPECT_EQ(c.render.width, 64);
  EXPECT_EQ(c.render.height, 48);
  EXPECT_NEAR(c.render.fov_y, 2 * std::atan(24.0 / 60.0) * 180 / 3.14159265358979323846, 1e-12);
  EXPECT_TRUE(std::any_of(notes.begin(), notes.end(), [](const std::string& n) {
    return n.find("fx 50 differs from fy 60") != std::string::npos;
  }));

  // default_camera_index = 1: that entry, carried into the simulation space, shows every point
  // where the trained view shows its preimage.
  p.default_camera_index = 1;
  c = convert();
  ASSERT_EQ(c.render.camera,
            fs::path(dir.file("sim_cameras.json")).lexically_normal().string() + ":1");
  const Camera sim = read_camera_spec(c.render.camera);
  EXPECT_EQ(sim.width, 80);
  EXPECT_EQ(sim.height, 60);
  EXPECT_EQ(sim.fx, 70);
  for (const PgVec3& q : std::vector<PgVec3>{{0, 0, 0}, {1.2, 0.3, -0.7}, {-2, 2, 1.5}}) {
    const auto want = project(b, q), got = project(sim, pre.map.to_sim(q));
    EXPECT_NEAR(got[0], want[0], 1e-9);
    EXPECT_NEAR(got[1], want[1], 1e-9);
  }
  // An index beyond cameras.json is PhysGaussian's IndexError: an InputError naming the key.
  p.default_camera_index = 2;
  try {
    convert();
    ADD_FAILURE() << "index 2 of 2 cameras accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("default_camera_index"), std::string::npos) << e.what();
  }
  // Without cameras.json the deck's camera frames the object; without a scenery file the
  // Gaussians outside sim_area are not drawn.
  files = PhysGaussianDeckFiles{};
  p.default_camera_index = 0;
  c = convert();
  EXPECT_EQ(c.render.camera, "auto");
  EXPECT_EQ(c.render.scenery, "");
}
