// PhysGaussian configs (utils/decode_param.py, gs_simulation.py, mpm_solver_warp/ of the
// PhysGaussian release) read exactly and converted to gen4d decks. Where the paper and the code
// differ, the code is followed.
//
// Reading. Every key decode_param.py reads is accepted with its default; any other key is an
// error (decode_param silently ignores unknown keys, so a typo would change a run unnoticed).
// Defaults that decode_param leaves to MPM_Simulator_WARP are the solver's: yield_stress 0,
// hardening 0 (off), xi 0, friction_angle 25, plastic_viscosity 0, softening 0.1,
// rpic_damping 0, grid_v_damping_scale 1.1 (no damping). Values PhysGaussian rejects are
// errors here too (nu outside [0, 0.5], unknown material / boundary type, a missing required
// boundary key, rotation lists of unequal length or an axis outside 0..2, sim_area without 6
// numbers, a sticky surface with friction). Differences of the reader:
// - g absent: decode_param's default is the scalar 9.8, which the solver indexes as a vector
//   and fails on; gen4d takes (0, 0, -9.8).
// - additional_material_params entries take only point, size, E, nu, density (the only keys
//   the solver reads from them).
// - surface must be sticky, slip, cut or separate (PhysGaussian turns any other word into
//   separate).
// - release_particles_sequentially's normal must pick one axis (PhysGaussian takes the last
//   non-zero component).
// - particle_filling accepts max_particles_per_cell as well as PhysGaussian's spelling
//   max_partciels_per_cell (not both).
//
// Preprocessing (gs_simulation.py): opacity > opacity_threshold (strict); the rotations of
// rotation_degree / rotation_axis in list order (exact pi; PhysGaussian uses 3.1415926);
// the crop to sim_area, strictly inside, on the rotated positions; the selection scaled about
// its bounding box's centre c so that its longest side is `scale`, and shifted to (1, 1, 1):
// sim = s (R x - c) + 1 with s = scale / longest side. Covariances follow (s^2 R A R^T). The
// harmonics rotate with R here; PhysGaussian instead maps positions and covariances back to the
// trained space for rendering, which shows the same colours. The unselected Gaussians are
// mapped by the same map (PhysGaussian renders them in the trained space).
//
// Deck. The deck runs in simulation space: [mpm] lo = (0, 0, 0), hi = grid_lim (PhysGaussian's
// grid has its nodes at i dx for i < n_grid, so its box ends one cell short of grid_lim),
// domain.voxel_size = grid_lim / n_grid, mpm.substep = "fixed" (PhysGaussian's substeps never
// adapt). simulation.dt = substep_dt, end_time = frame_dt frame_num, output.frame_interval =
// frame_dt: gen4d rounds frame_dt / substep_dt to whole substeps, PhysGaussian truncates
// (int(0.04 / 2e-5) = 1999). simulation.gravity = g. A particle reaching the grid's last two
// node layers is clamped back inside (mpm.out_of_domain = "clamp", counted in the progress
// line); PhysGaussian indexes past its grid arrays there (illegal memory accesses on the GPU,
// its issues #10, #11 and #35).
// [[geometry]] type "splats": the trained PLY with scale s, rotate_axis / rotate_degrees the
// axis and angle of the composite R, translate 1 - s c, and opacity_threshold; or, for a PLY
// written from the preprocessed selection, that file untransformed (the only way to honour
// sim_area; the Gaussians outside it, written to their own PLY, become [render] scenery drawn
// unmoved in every frame, as PhysGaussian draws them). gen4d keeps opacity == threshold,
// PhysGaussian drops it.
// Materials (E -> youngs_modulus, nu -> poisson_ratio, density):
// - jelly -> fixed_corotated.
// - metal -> von_mises. PhysGaussian yields when |dev tau| > yield_stress, gen4d when
//   |dev tau| > sqrt(2/3) sigma_y: yield_stress -> sqrt(3/2) yield_stress. With hardening = 1
//   PhysGaussian raises its yield_stress by 2 mu xi delta_gamma after each return, gen4d's
//   linear hardening raises sqrt(2/3) sigma_y by (2/3) H delta_gamma: hardening -> 3 mu xi
//   (mu = E / (2 (1 + nu))), applied inside gen4d's consistent return rather than after it.
// - sand -> drucker_prager with friction_angle (the same cone slope
//   alpha = sqrt(2/3) 2 sin(phi) / (3 - sin(phi))) and no cohesion. PhysGaussian gives sand
//   particles uniform volumes; gen4d's splat particles share their cell's volume.
// - foam (PhysGaussian's viscoplastic paste) -> herschel_bulkley with flow_index 1:
//   PhysGaussian yields at |s| > sqrt(2/3) yield_stress, gen4d at |s| > sqrt(2) tau_y:
//   yield_stress -> yield_stress / sqrt(3); plastic_viscosity eta -> consistency eta / 2.
//   PhysGaussian relaxes with mu tr(b) / 3 in place of mu.
// - plasticine -> von_mises as metal; its softening (yield stress lowered by softening times
//   the plastic strain increment, the material losing all stiffness at zero yield stress) has
//   no gen4d key, and PhysGaussian's plasticine stress is fixed corotated, gen4d's von_mises
//   StVK-Hencky.
// - snow -> "snow" with E, nu, density. PhysGaussian has no snow return mapping and computes
//   no stress for it (its snow is stress-free); gen4d's is a snow model.
// particle_filling -> the splats part's fill_cells (its n_grid rescaled from the simulation box
// to the object; its other keys at PhysGaussian's defaults, with a note where they differ).
// rpic_damping -> mpm.rpic_damping (r in (0, 1]: C -> (1 - r) C + r skew(C) in P2G; below
// -0.001: PIC, -1); other non-zero values (PhysGaussian extrapolates the blend) are left out with a
// note. grid_v_damping_scale in (0, 1) -> mpm.grid_velocity_scale (grid velocities times it every
// substep, after gravity). additional_material_params -> [[material]] entries after the first,
// each the base model with the box's E, nu and density, bound to lo / hi = point -/+ size.
// pic_damping has no gen4d key (PhysGaussian's code reads it and never uses it).
// Boundary conditions ([[boundary]]; start_time -> start, end_time -> end, a start before 0 is
// 0, an entry that never acts is left out with a note):
// - cuboid -> cuboid, lo / hi = point -/+ size, velocity, motion = "moving" when the velocity
//   is not zero (PhysGaussian moves the box by velocity dt every active substep). reset = 1 ->
//   reset_duration = 15 substep_dt: every grid velocity zeroed for 15 substeps after end_time.
//   PhysGaussian's reset also zeroes them at every substep before start_time (its test is "not
//   active"); gen4d does not, with a note when start_time > 0.
// - particle_impulse -> particle_impulse over point -/+ size (default (1,1,1) -/+ (1,1,1)),
//   end = start + num_dt substep_dt. PhysGaussian gives every particle in the box the velocity
//   change force dt / m_p; gen4d shares a total force by mass. The total is force times the
//   number of selected Gaussians in the box at rest (the same accelerations when the
//   particles' masses are equal).
// - bounding_box -> bounding_box with mpm.boundary_layers 3 (PhysGaussian's padding). Without
//   one PhysGaussian has no walls: the deck sets mpm.boundary_layers = 0.
// - enforce_particle_translation -> enforce_particle_translation, lo / hi = point -/+ size.
// - surface_collider -> surface_collider with point, normal, surface, friction. PhysGaussian
//   computes the slip / separate velocity and then stores zero (every non-cut collider
//   sticks); gen4d keeps slip and separate as written. "cut" -> surface "cut" with the cut
//   lo = (0, 0, 0.4), hi = (grid_lim, grid_lim, 0.53) and cut_scale 0.3 (PhysGaussian's
//   hard-coded band 0.4 <= z <= 0.53): there the velocity keeps 0.3 of its tangential part,
//   elsewhere behind the plane it stops. PhysGaussian zeroes the y component instead of the
//   normal one (the same for a normal along y; noted otherwise); it ignores friction.
// - release_particles_sequentially -> release_particles_sequentially with normal the axis
//   pointing from start_position to end_position and layers = num_layers (PhysGaussian
//   overrides num_layers with 50). PhysGaussian holds slabs of the span
//   |x - end_position| < |start_position - end_position| and releases layer i at
//   end_time (i + 1) / 50; gen4d layers the object's extent along the normal and releases
//   layer k at start + (end - start) k / layers.
// - enforce_particle_velocity_rotation -> enforce_particle_velocity_rotation with
//   half_height / radius, angular_velocity = -rotation_scale n and velocity = translation_scale
//   n (n the unit normal; PhysGaussian's frame (h1, h2 = h1 x n) turns about -n). PhysGaussian
//   divides by the distance to the axis (NaN on it); gen4d's rigid field is defined there.
// PhysGaussian selects the particles of particle conditions once, at rest; gen4d at every
// substep.
// Camera: default_camera_index < 0 -> [render] camera "orbit" in simulation space: center
// mpm_space_viewpoint_center, up mpm_space_vertical_upward_axis, radius s init_radius. Its
// azimuth 0 lies along R h1 with h1 the Gram-Schmidt of (1, 1, 1) against the trained-space
// vertical, and grows clockwise about up (gen4d's grows counter-clockwise): azimuth ->
// phi0 - init_azimuthm, phi0 the angle of R h1 in gen4d's orbit frame. With move_camera,
// PhysGaussian's image k (the state after k + 1 frames) uses the view of frame k; gen4d's
// frame k + 1 shows that state, so the deck starts one step back: azimuth + delta_a,
// elevation - delta_e, s (init_radius - delta_r), d_azimuth = -delta_a, d_elevation =
// delta_e, d_radius = s delta_r. The orbit's width, height and fov_y are those of the model's
// first cameras.json entry (gen4d's orbit has square pixels). default_camera_index >= 0: that
// entry of the model's cameras.json, carried into the simulation space (position by the map,
// camera-to-world rotation R C; size and focal lengths kept) and written beside the deck;
// without a cameras.json the deck's camera frames the object. show_hint is not honoured.
// Images: [render] layout "physgaussian" (gs_simulation.py's names: image k, f"{k}.png"
// zero-padded to 8 characters, shows the state after k + 1 frames; video output.mp4), fps =
// int(1 / frame_dt), a black background (PhysGaussian's default).
#include "gaussians/PhysGaussianConfig.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <utility>

#include "core/Error.hpp"
#include "gaussians/DeckSplats.hpp"
#include "gaussians/Json.hpp"

namespace gen4d::gaussians {

namespace {

constexpr double kPi = 3.14159265358979323846;

//! Typed access to a config's values; every failure names the file, line and key.
class Reader {
 public:
  explicit Reader(std::string source) : source_(std::move(source)) {}

  [[noreturn]] void fail(int line, const std::string& key, const std::string& message) const {
    throw InputError(fmt::format("{}:{}: key '{}': {}", source_, line, key, message));
  }
  void check(bool ok, const JsonValue& v, const std::string& key, const std::string& msg) const {
    if (!ok) fail(v.line(), key, msg);
  }

  double number(const JsonValue& v, const std::string& key) const {
    if (!v.is_number())
      fail(v.line(), key, fmt::format("expected a number, got {}", json_type_name(v.type())));
    return v.as_number();
  }
  long integer(const JsonValue& v, const std::string& key) const {
    if (!v.is_number() || v.as_number() != std::floor(v.as_number()) ||
        std::fabs(v.as_number()) > 2147483647.0)
      fail(v.line(), key, "expected an integer");
    return static_cast<long>(v.as_number());
  }
  bool boolean(const JsonValue& v, const std::string& key) const {
    if (!v.is_bool())
      fail(v.line(), key, fmt::format("expected true or false, got {}", json_type_name(v.type())));
    return v.as_bool();
  }
  const std::string& string(const JsonValue& v, const std::string& key) const {
    if (!v.is_string())
      fail(v.line(), key, fmt::format("expected a string, got {}", json_type_name(v.type())));
    return v.as_string();
  }
  template <std::size_t N>
  std::array<double, N> numbers(const JsonValue& v, const std::string& key) const {
    const std::string what = fmt::format("expected an array of {} numbers", N);
    if (!v.is_array() || v.items().size() != N) fail(v.line(), key, what);
    std::array<double, N> out{};
    for (std::size_t i = 0; i < N; ++i) {
      if (!v.items()[i].is_number()) fail(v.items()[i].line(), key, what);
      out[i] = v.items()[i].as_number();
    }
    return out;
  }
  PgVec3 vec3(const JsonValue& v, const std::string& key) const { return numbers<3>(v, key); }
  const std::vector<JsonValue>& array(const JsonValue& v, const std::string& key) const {
    if (!v.is_array())
      fail(v.line(), key, fmt::format("expected an array, got {}", json_type_name(v.type())));
    return v.items();
  }
  void object(const JsonValue& v, const std::string& key) const {
    if (!v.is_object())
      fail(v.line(), key, fmt::format("expected an object, got {}", json_type_name(v.type())));
  }

 private:
  std::string source_;
};

std::string joined(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& item : items) out += (out.empty() ? "" : ", ") + item;
  return out;
}

bool nonzero(const PgVec3& v) {
  return v[0] != 0 || v[1] != 0 || v[2] != 0;
}

//! Keys each boundary type takes (besides "type") and which of them are required.
struct BoundaryKeys {
  std::vector<std::string> allowed;
  std::vector<std::string> required;
};

BoundaryKeys boundary_keys(const std::string& type) {
  if (type == "cuboid")
    return {{"point", "size", "velocity", "start_time", "end_time", "reset"},
            {"point", "size", "velocity"}};
  if (type == "particle_impulse")
    return {{"force", "num_dt", "point", "size", "start_time"}, {"force"}};
  if (type == "bounding_box") return {{}, {}};
  if (type == "enforce_particle_translation") {
    std::vector<std::string> k = {"point", "size", "velocity", "start_time", "end_time"};
    return {k, k};
  }
  if (type == "surface_collider") {
    std::vector<std::string> k = {"point",    "normal",     "surface",
                                  "friction", "start_time", "end_time"};
    return {k, k};
  }
  if (type == "release_particles_sequentially") {
    std::vector<std::string> k = {"normal",     "start_position", "end_position",
                                  "num_layers", "start_time",     "end_time"};
    return {k, k};
  }
  std::vector<std::string> k = {
      "point",      "normal",  "half_height_and_radius", "rotation_scale", "translation_scale",
      "start_time", "end_time"};  // enforce_particle_velocity_rotation
  return {k, k};
}

PhysGaussianBoundary read_boundary(const Reader& r, const JsonValue& v, std::size_t index) {
  const std::string base = fmt::format("boundary_conditions[{}]", index);
  r.object(v, base);
  PhysGaussianBoundary b;
  b.line = v.line();
  const JsonValue* type = v.find("type");
  if (!type) r.fail(v.line(), base + ".type", "is required");
  b.type = r.string(*type, base + ".type");
  static const std::set<std::string> kTypes = {"cuboid",
                                               "particle_impulse",
                                               "bounding_box",
                                               "enforce_particle_translation",
                                               "surface_collider",
                                               "release_particles_sequentially",
                                               "enforce_particle_velocity_rotation"};
  if (!kTypes.count(b.type))
    r.fail(type->line(), base + ".type",
           fmt::format("unknown boundary condition type '{}' (known: cuboid, particle_impulse, "
                       "bounding_box, enforce_particle_translation, surface_collider, "
                       "release_particles_sequentially, enforce_particle_velocity_rotation)",
                       b.type));
  const BoundaryKeys keys = boundary_keys(b.type);
  for (const auto& [key, value] : v.members()) {
    if (key == "type") continue;
    if (std::find(keys.allowed.begin(), keys.allowed.end(), key) == keys.allowed.end())
      r.fail(value.line(), base + "." + key,
             fmt::format("unknown key for type '{}'{}", b.type,
                         keys.allowed.empty() ? std::string(" (it takes none)")
                                              : " (known: " + joined(keys.allowed) + ")"));
  }
  for (const std::string& key : keys.required)
    if (!v.find(key))
      r.fail(v.line(), base + "." + key, fmt::format("is required by type '{}'", b.type));
  if (b.type == "cuboid") b.end_time = 1e3;
  for (const auto& [key, value] : v.members()) {
    const std::string name = base + "." + key;
    if (key == "point") b.point = r.vec3(value, name);
    if (key == "size") b.size = r.vec3(value, name);
    if (key == "velocity") b.velocity = r.vec3(value, name);
    if (key == "force") b.force = r.vec3(value, name);
    if (key == "normal") {
      b.normal = r.vec3(value, name);
      r.check(nonzero(b.normal), value, name, "must not be the zero vector");
    }
    if (key == "start_time") b.start_time = r.number(value, name);
    if (key == "end_time") b.end_time = r.number(value, name);
    if (key == "reset") b.reset = static_cast<int>(r.integer(value, name));
    if (key == "num_dt") {
      b.num_dt = static_cast<int>(r.integer(value, name));
      r.check(b.num_dt >= 0, value, name, fmt::format("must be >= 0, got {}", b.num_dt));
    }
    if (key == "surface") {
      b.surface = r.string(value, name);
      r.check(b.surface == "sticky" || b.surface == "slip" || b.surface == "separate" ||
                  b.surface == "cut",
              value, name,
              fmt::format("expected \"sticky\", \"slip\", \"separate\" or \"cut\", got \"{}\"",
                          b.surface));
    }
    if (key == "friction") {
      b.friction = r.number(value, name);
      r.check(b.friction >= 0, value, name, fmt::format("must be >= 0, got {}", b.friction));
    }
    if (key == "start_position") b.start_position = r.number(value, name);
    if (key == "end_position") b.end_position = r.number(value, name);
    if (key == "num_layers") {
      b.num_layers = static_cast<int>(r.integer(value, name));
      r.check(b.num_layers >= 1, value, name, fmt::format("must be >= 1, got {}", b.num_layers));
    }
    if (key == "half_height_and_radius") {
      b.half_height_and_radius = r.numbers<2>(value, name);
      r.check(b.half_height_and_radius[0] > 0 && b.half_height_and_radius[1] > 0, value, name,
              "half height and radius must be > 0");
    }
    if (key == "rotation_scale") b.rotation_scale = r.number(value, name);
    if (key == "translation_scale") b.translation_scale = r.number(value, name);
  }
  if (b.type == "surface_collider" && b.surface == "sticky" && b.friction != 0)
    r.fail(v.find("friction")->line(), base + ".friction",
           "must be 0 on a sticky surface (PhysGaussian rejects it)");
  if (b.type == "release_particles_sequentially") {
    const int axes = (b.normal[0] != 0) + (b.normal[1] != 0) + (b.normal[2] != 0);
    r.check(axes == 1, *v.find("normal"), base + ".normal",
            "must have exactly one non-zero component (the axis of the layers)");
    r.check(b.start_position != b.end_position, *v.find("end_position"), base + ".end_position",
            "must differ from start_position");
  }
  return b;
}

PhysGaussianMaterialBox read_material_box(const Reader& r, const JsonValue& v, std::size_t index,
                                          double density) {
  const std::string base = fmt::format("additional_material_params[{}]", index);
  r.object(v, base);
  PhysGaussianMaterialBox m;
  m.line = v.line();
  m.density = density;
  for (const char* key : {"point", "size", "E", "nu"})
    if (!v.find(key)) r.fail(v.line(), base + "." + key, "is required");
  for (const auto& [key, value] : v.members()) {
    const std::string name = base + "." + key;
    if (key == "point") {
      m.point = r.vec3(value, name);
    } else if (key == "size") {
      m.size = r.vec3(value, name);
    } else if (key == "E") {
      m.E = r.number(value, name);
    } else if (key == "nu") {
      m.nu = r.number(value, name);
    } else if (key == "density") {
      m.density = r.number(value, name);
    } else {
      r.fail(value.line(), name, "unknown key (known: point, size, E, nu, density)");
    }
  }
  return m;
}

PhysGaussianFilling read_filling(const Reader& r, const JsonValue& v, int n_grid) {
  r.object(v, "particle_filling");
  PhysGaussianFilling f;
  f.n_grid = 4 * n_grid;
  const JsonValue* misspelled = v.find("max_partciels_per_cell");
  const JsonValue* spelled = v.find("max_particles_per_cell");
  if (misspelled && spelled)
    r.fail(spelled->line(), "particle_filling.max_particles_per_cell",
           "give either max_partciels_per_cell (PhysGaussian's spelling) or "
           "max_particles_per_cell, not both");
  for (const auto& [key, value] : v.members()) {
    const std::string name = "particle_filling." + key;
    if (key == "n_grid") {
      f.n_grid = static_cast<int>(r.integer(value, name));
      r.check(f.n_grid >= 1, value, name, fmt::format("must be >= 1, got {}", f.n_grid));
    } else if (key == "density_threshold") {
      f.density_threshold = r.number(value, name);
    } else if (key == "search_threshold") {
      f.search_threshold = r.number(value, name);
    } else if (key == "max_particles_num") {
      f.max_particles_num = r.integer(value, name);
      r.check(f.max_particles_num >= 0, value, name, "must be >= 0");
    } else if (key == "max_partciels_per_cell" || key == "max_particles_per_cell") {
      f.max_particles_per_cell = static_cast<int>(r.integer(value, name));
      r.check(f.max_particles_per_cell >= 1, value, name, "must be >= 1");
    } else if (key == "search_exclude_direction") {
      f.search_exclude_direction = static_cast<int>(r.integer(value, name));
    } else if (key == "ray_cast_direction") {
      f.ray_cast_direction = static_cast<int>(r.integer(value, name));
    } else if (key == "boundary") {
      if (!value.is_null()) f.boundary = r.numbers<6>(value, name);
    } else if (key == "smooth") {
      f.smooth = r.boolean(value, name);
    } else if (key == "visualize") {
      f.visualize = r.boolean(value, name);
    } else {
      r.fail(value.line(), name,
             "unknown key (known: n_grid, density_threshold, search_threshold, "
             "max_particles_num, max_partciels_per_cell, max_particles_per_cell, "
             "search_exclude_direction, ray_cast_direction, boundary, smooth, visualize)");
    }
  }
  return f;
}

const char* const kTopKeys[] = {"material",
                                "grid_lim",
                                "n_grid",
                                "nu",
                                "E",
                                "yield_stress",
                                "hardening",
                                "xi",
                                "friction_angle",
                                "plastic_viscosity",
                                "g",
                                "density",
                                "rpic_damping",
                                "pic_damping",
                                "softening",
                                "opacity_threshold",
                                "grid_v_damping_scale",
                                "additional_material_params",
                                "boundary_conditions",
                                "substep_dt",
                                "frame_dt",
                                "frame_num",
                                "rotation_degree",
                                "rotation_axis",
                                "sim_area",
                                "scale",
                                "particle_filling",
                                "mpm_space_viewpoint_center",
                                "mpm_space_vertical_upward_axis",
                                "default_camera_index",
                                "show_hint",
                                "init_azimuthm",
                                "init_elevation",
                                "init_radius",
                                "delta_a",
                                "delta_e",
                                "delta_r",
                                "move_camera"};

std::array<double, 9> matmul(const std::array<double, 9>& a, const std::array<double, 9>& b) {
  std::array<double, 9> c{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) c[3 * i + j] += a[3 * i + k] * b[3 * k + j];
  return c;
}

PgVec3 mat_vec(const std::array<double, 9>& m, const PgVec3& v) {
  PgVec3 o{};
  for (int i = 0; i < 3; ++i) o[i] = m[3 * i] * v[0] + m[3 * i + 1] * v[1] + m[3 * i + 2] * v[2];
  return o;
}

PgVec3 mat_tvec(const std::array<double, 9>& m, const PgVec3& v) {
  PgVec3 o{};
  for (int i = 0; i < 3; ++i) o[i] = m[i] * v[0] + m[3 + i] * v[1] + m[6 + i] * v[2];
  return o;
}

double dot(const PgVec3& a, const PgVec3& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

PgVec3 cross(const PgVec3& a, const PgVec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

PgVec3 normalized(const PgVec3& v) {
  const double n = std::sqrt(dot(v, v));
  return {v[0] / n, v[1] / n, v[2] / n};
}

//! Axis (unit) and angle (degrees, in [0, 180]) of a rotation matrix; (0, 0, 1) and 0 for I.
std::pair<PgVec3, double> axis_angle(const std::array<double, 9>& R) {
  // Quaternion by Shepperd's method, then angle = 2 atan2(|v|, w) with w >= 0.
  const double tr = R[0] + R[4] + R[8];
  double w, x, y, z;
  if (tr >= R[0] && tr >= R[4] && tr >= R[8]) {
    const double s = 2 * std::sqrt(1 + tr);
    w = s / 4;
    x = (R[7] - R[5]) / s;
    y = (R[2] - R[6]) / s;
    z = (R[3] - R[1]) / s;
  } else if (R[0] >= R[4] && R[0] >= R[8]) {
    const double s = 2 * std::sqrt(1 + R[0] - R[4] - R[8]);
    w = (R[7] - R[5]) / s;
    x = s / 4;
    y = (R[1] + R[3]) / s;
    z = (R[2] + R[6]) / s;
  } else if (R[4] >= R[8]) {
    const double s = 2 * std::sqrt(1 + R[4] - R[0] - R[8]);
    w = (R[2] - R[6]) / s;
    x = (R[1] + R[3]) / s;
    y = s / 4;
    z = (R[5] + R[7]) / s;
  } else {
    const double s = 2 * std::sqrt(1 + R[8] - R[0] - R[4]);
    w = (R[3] - R[1]) / s;
    x = (R[2] + R[6]) / s;
    y = (R[5] + R[7]) / s;
    z = s / 4;
  }
  if (w < 0) {
    w = -w;
    x = -x;
    y = -y;
    z = -z;
  }
  const double vn = std::sqrt(x * x + y * y + z * z);
  if (!(vn > 1e-15)) return {{0, 0, 1}, 0.0};
  return {{x / vn, y / vn, z / vn}, 2 * std::atan2(vn, w) * 180 / kPi};
}

SplatSet subset(const SplatSet& s, const std::vector<std::size_t>& idx) {
  SplatSet o;
  o.sh_degree = s.sh_degree;
  const std::size_t K3 = 3 * static_cast<std::size_t>(s.coefficients());
  for (std::size_t i : idx) {
    o.position.insert(o.position.end(), &s.position[3 * i], &s.position[3 * i] + 3);
    o.scale.insert(o.scale.end(), &s.scale[3 * i], &s.scale[3 * i] + 3);
    o.rotation.insert(o.rotation.end(), &s.rotation[4 * i], &s.rotation[4 * i] + 4);
    o.opacity.push_back(s.opacity[i]);
    o.sh.insert(o.sh.end(), &s.sh[K3 * i], &s.sh[K3 * i] + K3);
  }
  return o;
}

// ---- deck text ----

std::string num(double v) {
  return fmt::format("{}", v);
}

std::string vec(const PgVec3& v) {
  return fmt::format("[{}, {}, {}]", num(v[0]), num(v[1]), num(v[2]));
}

std::string quoted(const std::string& s) {
  std::string out = "\"";
  for (const char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    if (ch == '"' || ch == '\\') {
      out += '\\';
      out += ch;
    } else if (c < 0x20 || c == 0x7f) {
      out += fmt::format("\\u{:04X}", static_cast<unsigned>(c));
    } else {
      out += ch;
    }
  }
  return out + "\"";
}

PgVec3 add(const PgVec3& a, const PgVec3& b, double f) {
  return {a[0] + f * b[0], a[1] + f * b[1], a[2] + f * b[2]};
}

//! A number key read straight into a member; `positive`: it must be > 0.
struct NumberKey {
  const char* name;
  double PhysGaussianParams::*member;
  bool positive;
};
constexpr NumberKey kNumberKeys[] = {
    {"grid_lim", &PhysGaussianParams::grid_lim, true},
    {"E", &PhysGaussianParams::E, true},
    {"yield_stress", &PhysGaussianParams::yield_stress, false},
    {"xi", &PhysGaussianParams::xi, false},
    {"friction_angle", &PhysGaussianParams::friction_angle, false},
    {"plastic_viscosity", &PhysGaussianParams::plastic_viscosity, false},
    {"rpic_damping", &PhysGaussianParams::rpic_damping, false},
    {"softening", &PhysGaussianParams::softening, false},
    {"opacity_threshold", &PhysGaussianParams::opacity_threshold, false},
    {"grid_v_damping_scale", &PhysGaussianParams::grid_v_damping_scale, false},
    {"substep_dt", &PhysGaussianParams::substep_dt, true},
    {"frame_dt", &PhysGaussianParams::frame_dt, true},
    {"scale", &PhysGaussianParams::scale, true},
};

//! A camera number that may be null (left unset).
struct OptionalKey {
  const char* name;
  std::optional<double> PhysGaussianParams::*member;
};
constexpr OptionalKey kOptionalKeys[] = {
    {"init_azimuthm", &PhysGaussianParams::init_azimuthm},
    {"init_elevation", &PhysGaussianParams::init_elevation},
    {"init_radius", &PhysGaussianParams::init_radius},
    {"delta_a", &PhysGaussianParams::delta_a},
    {"delta_e", &PhysGaussianParams::delta_e},
    {"delta_r", &PhysGaussianParams::delta_r},
};

template <class Key, std::size_t N>
const Key* find_key(const Key (&keys)[N], const std::string& name) {
  for (const Key& k : keys)
    if (name == k.name) return &k;
  return nullptr;
}
const NumberKey* find_number_key(const std::string& name) {
  return find_key(kNumberKeys, name);
}
const OptionalKey* find_optional_key(const std::string& name) {
  return find_key(kOptionalKeys, name);
}

}  // namespace

PhysGaussianParams read_physgaussian_config(const std::string& path) {
  const JsonValue root = read_json_file(path);
  const Reader r(path);
  if (!root.is_object())
    r.fail(root.line(), "(top level)",
           fmt::format("expected an object, got {}", json_type_name(root.type())));
  PhysGaussianParams p;
  p.source = path;
  for (const auto& [key, value] : root.members())
    if (std::find(std::begin(kTopKeys), std::end(kTopKeys), key) == std::end(kTopKeys))
      r.fail(value.line(), key, "unknown key (not read by PhysGaussian's decode_param)");
  // Keys that others' defaults depend on first.
  if (const JsonValue* v = root.find("n_grid")) {
    p.n_grid = static_cast<int>(r.integer(*v, "n_grid"));
    r.check(p.n_grid >= 1, *v, "n_grid", fmt::format("must be >= 1, got {}", p.n_grid));
  }
  if (const JsonValue* v = root.find("density")) {
    p.density = r.number(*v, "density");
    r.check(p.density > 0, *v, "density", fmt::format("must be > 0, got {}", p.density));
  }
  const JsonValue* axes = nullptr;
  const JsonValue* degrees = nullptr;
  for (const auto& [key, value] : root.members()) {
    const JsonValue& v = value;
    if (key == "material") {
      p.material = r.string(v, key);
      static const std::set<std::string> kMaterials = {"jelly", "metal", "sand",
                                                       "foam",  "snow",  "plasticine"};
      r.check(kMaterials.count(p.material), v, key,
              fmt::format("unknown material '{}' (known: jelly, metal, sand, foam, snow, "
                          "plasticine)",
                          p.material));
    } else if (const NumberKey* k = find_number_key(key)) {
      p.*k->member = r.number(v, key);
      if (k->positive)
        r.check(p.*k->member > 0, v, key, fmt::format("must be > 0, got {}", p.*k->member));
      if (k->member == &PhysGaussianParams::yield_stress) p.has_yield_stress = true;
    } else if (key == "nu") {
      p.nu = r.number(v, key);
      r.check(p.nu >= 0 && p.nu <= 0.5, v, key, fmt::format("must be in [0, 0.5], got {}", p.nu));
    } else if (key == "hardening") {
      p.hardening = static_cast<int>(r.integer(v, key));
    } else if (key == "g") {
      p.g = r.vec3(v, key);
      p.has_g = true;
    } else if (key == "pic_damping") {
      p.pic_damping = r.number(v, key);
    } else if (key == "additional_material_params") {
      const auto& items = r.array(v, key);
      for (std::size_t i = 0; i < items.size(); ++i)
        p.additional_material_params.push_back(read_material_box(r, items[i], i, p.density));
    } else if (key == "boundary_conditions") {
      const auto& items = r.array(v, key);
      for (std::size_t i = 0; i < items.size(); ++i)
        p.boundary_conditions.push_back(read_boundary(r, items[i], i));
    } else if (key == "frame_num") {
      p.frame_num = static_cast<int>(r.integer(v, key));
      r.check(p.frame_num >= 0, v, key, fmt::format("must be >= 0, got {}", p.frame_num));
    } else if (key == "rotation_degree") {
      degrees = &v;
      for (const JsonValue& d : r.array(v, key)) p.rotation_degree.push_back(r.number(d, key));
    } else if (key == "rotation_axis") {
      axes = &v;
      for (const JsonValue& a : r.array(v, key)) {
        const long axis = r.integer(a, key);
        r.check(axis >= 0 && axis <= 2, a, key,
                fmt::format("axis must be 0, 1 or 2, got {}", axis));
        p.rotation_axis.push_back(static_cast<int>(axis));
      }
    } else if (key == "sim_area") {
      if (!v.is_null()) {
        p.sim_area = r.numbers<6>(v, key);
        for (int d = 0; d < 3; ++d)
          r.check((*p.sim_area)[2 * d] < (*p.sim_area)[2 * d + 1], v, key,
                  "each lower bound must be below its upper bound (x0, x1, y0, y1, z0, z1)");
      }
    } else if (key == "particle_filling") {
      if (!v.is_null()) p.particle_filling = read_filling(r, v, p.n_grid);
    } else if (key == "mpm_space_viewpoint_center") {
      p.mpm_space_viewpoint_center = r.vec3(v, key);
    } else if (key == "mpm_space_vertical_upward_axis") {
      p.mpm_space_vertical_upward_axis = r.vec3(v, key);
      r.check(nonzero(p.mpm_space_vertical_upward_axis), v, key, "must not be the zero vector");
    } else if (key == "default_camera_index") {
      p.default_camera_index = static_cast<int>(r.integer(v, key));
    } else if (key == "show_hint") {
      p.show_hint = r.boolean(v, key);
    } else if (key == "move_camera") {
      p.move_camera = r.boolean(v, key);
    } else if (const OptionalKey* k = find_optional_key(key)) {
      if (!v.is_null()) p.*k->member = r.number(v, key);
    }
  }
  if (p.rotation_degree.size() != p.rotation_axis.size()) {
    const JsonValue* at = axes ? axes : degrees;
    r.fail(at->line(), "rotation_axis",
           fmt::format("has {} entries but rotation_degree has {}", p.rotation_axis.size(),
                       p.rotation_degree.size()));
  }
  if (p.default_camera_index < 0 && !p.show_hint) {
    // PhysGaussian asserts these for its orbit camera.
    const std::pair<const char*, bool> needed[] = {
        {"init_azimuthm", p.init_azimuthm.has_value()},
        {"init_elevation", p.init_elevation.has_value()},
        {"init_radius", p.init_radius.has_value()},
        {"delta_a", !p.move_camera || p.delta_a.has_value()},
        {"delta_e", !p.move_camera || p.delta_e.has_value()},
        {"delta_r", !p.move_camera || p.delta_r.has_value()}};
    for (const auto& [key, present] : needed)
      if (!present)
        r.fail(root.find("default_camera_index")->line(), key,
               "is required by the orbit camera (default_camera_index < 0)");
  }
  return p;
}

PgVec3 PhysGaussianSimMap::to_sim(const PgVec3& world) const {
  const PgVec3 rw = mat_vec(rotation, world);
  PgVec3 o{};
  for (int d = 0; d < 3; ++d) o[d] = scale * (rw[d] - center[d]) + 1.0;
  return o;
}

PgVec3 PhysGaussianSimMap::to_world(const PgVec3& sim) const {
  PgVec3 u{};
  for (int d = 0; d < 3; ++d) u[d] = (sim[d] - 1.0) / scale + center[d];
  return mat_tvec(rotation, u);
}

PgVec3 PhysGaussianSimMap::translation() const {
  PgVec3 t{};
  for (int d = 0; d < 3; ++d) t[d] = 1.0 - scale * center[d];
  return t;
}

std::array<double, 9> physgaussian_rotation(const PhysGaussianParams& params) {
  std::array<double, 9> R{1, 0, 0, 0, 1, 0, 0, 0, 1};
  const std::size_t n = std::min(params.rotation_degree.size(), params.rotation_axis.size());
  for (std::size_t i = 0; i < n; ++i) {
    const double a = params.rotation_degree[i] * kPi / 180.0;
    const double c = std::cos(a), s = std::sin(a);
    std::array<double, 9> M{};
    switch (params.rotation_axis[i]) {
      case 0:
        M = {1, 0, 0, 0, c, -s, 0, s, c};
        break;
      case 1:
        M = {c, 0, s, 0, 1, 0, -s, 0, c};
        break;
      case 2:
        M = {c, -s, 0, s, c, 0, 0, 0, 1};
        break;
      default:
        throw InputError(fmt::format("{}: key 'rotation_axis': axis must be 0, 1 or 2, got {}",
                                     params.source, params.rotation_axis[i]));
    }
    R = matmul(M, R);
  }
  return R;
}

PhysGaussianPreprocessed preprocess_physgaussian(const SplatSet& trained,
                                                 const PhysGaussianParams& params) {
  trained.check_sizes();
  PhysGaussianPreprocessed out;
  const std::array<double, 9> R = physgaussian_rotation(params);
  PgVec3 lo{}, hi{};
  lo.fill(std::numeric_limits<double>::infinity());
  hi.fill(-std::numeric_limits<double>::infinity());
  for (std::size_t i = 0; i < trained.size(); ++i) {
    if (!(trained.opacity[i] > params.opacity_threshold)) continue;
    const PgVec3 p = mat_vec(
        R, {trained.position[3 * i], trained.position[3 * i + 1], trained.position[3 * i + 2]});
    bool inside = true;
    if (params.sim_area)
      for (int d = 0; d < 3; ++d)
        inside = inside && p[d] > (*params.sim_area)[2 * d] && p[d] < (*params.sim_area)[2 * d + 1];
    if (!inside) {
      out.rest_index.push_back(i);
      continue;
    }
    out.selected_index.push_back(i);
    for (int d = 0; d < 3; ++d) {
      lo[d] = std::min(lo[d], p[d]);
      hi[d] = std::max(hi[d], p[d]);
    }
  }
  if (out.selected_index.empty())
    throw InputError(fmt::format("{}: no Gaussian is left to simulate (opacity_threshold {}{})",
                                 params.source, params.opacity_threshold,
                                 params.sim_area ? " and sim_area select none" : ""));
  const double extent = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
  if (!(extent > 0))
    throw InputError(
        fmt::format("{}: the selected Gaussians have no extent, so key 'scale' cannot size them",
                    params.source));
  out.map.rotation = R;
  out.map.scale = params.scale / extent;
  for (int d = 0; d < 3; ++d) out.map.center[d] = 0.5 * (lo[d] + hi[d]);
  const PgVec3 t = out.map.translation();
  out.selected = subset(trained, out.selected_index);
  out.rest = subset(trained, out.rest_index);
  transform_splats(out.selected, out.map.scale, R, t);
  if (out.rest.size()) transform_splats(out.rest, out.map.scale, R, t);
  return out;
}

namespace {

using Notes = std::vector<std::string>;

[[noreturn]] void fail_key(const PhysGaussianParams& p, const std::string& key,
                           const std::string& msg) {
  throw InputError(fmt::format("{}: key '{}': {}", p.source, key, msg));
}

//! fill_cells of the deck: PhysGaussian's filling grid spans the simulation box (grid_lim) with
//! n_grid cells; gen4d's spans the object, whose longest side the preprocessing made `scale`.
int deck_fill_cells(const PhysGaussianParams& p) {
  return p.particle_filling ? std::max(1, static_cast<int>(std::lround(p.particle_filling->n_grid *
                                                                       p.scale / p.grid_lim)))
                            : 0;
}

//! [simulation], [domain] and the splats [[geometry]].
std::string deck_object(const PhysGaussianParams& p, const std::string& ply_path,
                        const PhysGaussianPreprocessed& pre, PlySpace space,
                        const PhysGaussianDeckFiles* files, Notes& notes) {
  const PhysGaussianSimMap& map = pre.map;
  std::string d = fmt::format("# Converted from the PhysGaussian config {}\n", p.source);
  d += "\n[simulation]\nname = \"physgaussian\"\n";
  d += fmt::format("dt = {}\n", num(p.substep_dt));
  d += fmt::format("end_time = {}\n", num(p.frame_dt * p.frame_num));
  d += fmt::format("gravity = {}\n", vec(p.g));
  if (!p.has_g)
    notes.push_back(
        "g: absent; PhysGaussian's default (the scalar 9.8) makes its solver fail, gen4d uses "
        "[0, 0, -9.8]");
  const double steps = p.frame_dt / p.substep_dt;
  if (static_cast<long>(steps) != std::lround(steps))
    notes.push_back(fmt::format(
        "substep_dt: PhysGaussian runs int(frame_dt / substep_dt) = {} substeps per frame, "
        "gen4d rounds frame_dt / dt to {}",
        static_cast<long>(steps), std::lround(steps)));
  d += fmt::format("\n[domain]\nvoxel_size = {}\n", num(p.grid_lim / p.n_grid));

  d += "\n[[geometry]]\ntype = \"splats\"\n";
  d += fmt::format("file = {}\n", quoted(ply_path));
  const int fill_cells = deck_fill_cells(p);
  if (fill_cells > 0) d += fmt::format("fill_cells = {}\n", fill_cells);
  if (space == PlySpace::Trained) {
    const auto [axis, degrees] = axis_angle(map.rotation);
    d += fmt::format("scale = {}\n", num(map.scale));
    d += fmt::format("translate = {}\n", vec(map.translation()));
    d += fmt::format("rotate_axis = {}\n", vec(axis));
    d += fmt::format("rotate_degrees = {}\n", num(degrees));
    d += fmt::format("opacity_threshold = {}\n", num(p.opacity_threshold));
    if (p.sim_area)
      notes.push_back(
          "sim_area: a splats geometry has no crop key; this deck simulates every Gaussian of "
          "the file (write the preprocessed selection with write_splats_ply and convert with "
          "PlySpace::Simulation to honour the crop; the unselected Gaussians are then not "
          "drawn)");
    notes.push_back(
        "opacity_threshold: gen4d keeps a Gaussian whose opacity equals the threshold, "
        "PhysGaussian drops it");
  } else {
    d += "opacity_threshold = 0\n";
    if (p.sim_area && pre.rest.size() && !(files && !files->scenery_ply.empty()))
      notes.push_back(
          fmt::format("sim_area: the {} Gaussians outside it are not drawn (no scenery file "
                      "given)",
                      pre.rest.size()));
    else if (p.sim_area && pre.rest.size())
      notes.push_back(
          fmt::format("sim_area: the {} Gaussians outside it are drawn unmoved from {} "
                      "([render] scenery)",
                      pre.rest.size(), files->scenery_ply));
  }
  return d;
}

//! gen4d's MPM model for PhysGaussian's material name.
std::string deck_model(const std::string& material) {
  std::string model;
  if (material == "jelly") model = "fixed_corotated";
  if (material == "metal" || material == "plasticine") model = "von_mises";
  if (material == "sand") model = "drucker_prager";
  if (material == "foam") model = "herschel_bulkley";
  if (material == "snow") model = "snow";
  return model;
}

//! The keys of the model with these elastic constants; `notes` (when given) receives the notes.
std::string material_keys(const PhysGaussianParams& p, const std::string& model, double E,
                          double nu, double density, Notes* notes) {
  std::string m;
  auto say = [&](std::string s) {
    if (notes) notes->push_back(std::move(s));
  };
  const double mu = E / (2 * (1 + nu));
  m += fmt::format("model = {}\n", quoted(model));
  m += fmt::format("youngs_modulus = {}\n", num(E));
  m += fmt::format("poisson_ratio = {}\n", num(nu));
  m += fmt::format("density = {}\n", num(density));
  if (nu >= 0.5) say("nu: 0.5 is accepted by PhysGaussian, gen4d needs nu < 0.5");
  say(fmt::format("material: {} -> {}", p.material, model));
  if (model == "von_mises") {
    m += fmt::format("yield_stress = {}\n", num(std::sqrt(1.5) * p.yield_stress));
    say(
        fmt::format("yield_stress: PhysGaussian's |dev tau| bound {} -> uniaxial sigma_y = "
                    "sqrt(3/2) x that = {}",
                    num(p.yield_stress), num(std::sqrt(1.5) * p.yield_stress)));
    if (p.hardening == 1) {
      m += fmt::format("hardening = {}\n", num(3 * mu * p.xi));
      say(fmt::format("hardening = 1, xi = {}: linear hardening modulus 3 mu xi = {} Pa", num(p.xi),
                      num(3 * mu * p.xi)));
    }
    if (p.material == "plasticine")
      say(
          fmt::format("softening = {}: not honoured (gen4d's von_mises has no softening); "
                      "PhysGaussian's plasticine stress is fixed corotated, gen4d's von_mises "
                      "StVK-Hencky",
                      num(p.softening)));
  } else if (p.hardening == 1 || p.xi != 0) {
    say("hardening / xi: only metal and plasticine use them");
  }
  if (model == "drucker_prager") {
    m += fmt::format("friction_angle = {}\n", num(p.friction_angle));
    say("sand: PhysGaussian gives sand particles uniform volumes, gen4d shares each cell's "
        "volume among its Gaussians");
  }
  if (model == "herschel_bulkley") {
    m += fmt::format("yield_stress = {}\n", num(p.yield_stress / std::sqrt(3.0)));
    m += fmt::format("consistency = {}\n", num(p.plastic_viscosity / 2));
    m += "flow_index = 1\n";
    say("foam: yield_stress / sqrt(3) -> shear yield stress, plastic_viscosity / 2 -> "
        "consistency (PhysGaussian relaxes with mu tr(b) / 3 in place of mu)");
  }
  if (model == "snow")
    say("snow: PhysGaussian computes no stress for snow (no return mapping); gen4d's snow "
        "model is used instead");
  return m;
}

//! One [material], or [[material]] entries for additional_material_params (the base model with
//! the box's E, nu and density; later entries win where boxes overlap).
std::string deck_materials(const PhysGaussianParams& p, Notes& notes) {
  const std::string model = deck_model(p.material);
  if (p.additional_material_params.empty())
    return "\n[material]\n" + material_keys(p, model, p.E, p.nu, p.density, &notes);
  std::string d = "\n[[material]]\n" + material_keys(p, model, p.E, p.nu, p.density, &notes);
  for (const auto& box : p.additional_material_params) {
    d += fmt::format("\n[[material]]  # additional_material_params, line {}\n", box.line);
    d += fmt::format("lo = {}\n", vec(add(box.point, box.size, -1)));
    d += fmt::format("hi = {}\n", vec(add(box.point, box.size, 1)));
    d += material_keys(p, model, box.E, box.nu, box.density, nullptr);
  }
  notes.push_back(fmt::format(
      "additional_material_params: {} box(es) -> [[material]] entries bound to lo/hi = point "
      "-/+ size at the rest positions (PhysGaussian's boxes are open, gen4d's closed)",
      p.additional_material_params.size()));
  return d;
}

//! [mpm] keys of rpic_damping and grid_v_damping_scale.
std::string deck_damping(const PhysGaussianParams& p, Notes& notes) {
  std::string keys;
  if (p.rpic_damping > 0 && p.rpic_damping <= 1)
    keys += fmt::format("rpic_damping = {}\n", num(p.rpic_damping));
  else if (p.rpic_damping < -0.001)
    keys += "rpic_damping = -1\n";  // PhysGaussian's PIC
  else if (p.rpic_damping != 0)
    notes.push_back(
        fmt::format("rpic_damping = {}: not honoured (gen4d blends C towards its skew part "
                    "for values in [0, 1] and uses PIC below -0.001); APIC is used",
                    num(p.rpic_damping)));
  if (p.grid_v_damping_scale > 0 && p.grid_v_damping_scale < 1)
    keys += fmt::format("grid_velocity_scale = {}\n", num(p.grid_v_damping_scale));
  else if (p.grid_v_damping_scale <= 0)
    notes.push_back(
        fmt::format("grid_v_damping_scale = {}: not honoured (gen4d's grid_velocity_scale is "
                    "in (0, 1])",
                    num(p.grid_v_damping_scale)));
  if (p.pic_damping)
    notes.push_back("pic_damping: read by PhysGaussian but used by none of its code");
  return keys;
}

//! The notes on particle_filling (only n_grid reaches the deck).
void note_filling(const PhysGaussianParams& p, Notes& notes) {
  if (!p.particle_filling) return;
  const PhysGaussianFilling& f = *p.particle_filling;
  const PhysGaussianFilling defaults;
  notes.push_back(
      fmt::format("particle_filling: n_grid {} over the box of grid_lim {} is fill_cells = {} "
                  "over the object of side {} (gen4d's filling bounds each Gaussian's "
                  "support and searches the nearest Gaussian with a k-d tree)",
                  f.n_grid, num(p.grid_lim), deck_fill_cells(p), num(p.scale)));
  if (f.density_threshold != defaults.density_threshold ||
      f.search_threshold != defaults.search_threshold ||
      f.max_particles_per_cell != defaults.max_particles_per_cell ||
      f.search_exclude_direction != defaults.search_exclude_direction ||
      f.ray_cast_direction != defaults.ray_cast_direction || f.boundary || f.smooth)
    notes.push_back(
        "particle_filling: only n_grid reaches the deck; its other keys take PhysGaussian's "
        "defaults (density_threshold 5, search_threshold 3, one particle per cell, rays "
        "excluding -z and cast along +z, no boundary, no smoothing)");
}

//! [solver], [mpm] (with the damping keys) and [output].
std::string deck_solver(const PhysGaussianParams& p, const std::string& damping, Notes& notes) {
  std::string d = "\n[solver]\nmethod = \"mpm\"\n";
  const bool walls =
      std::any_of(p.boundary_conditions.begin(), p.boundary_conditions.end(),
                  [](const PhysGaussianBoundary& b) { return b.type == "bounding_box"; });
  d += "\n[mpm]\nlo = [0, 0, 0]\n";
  d += fmt::format("hi = {}\n", vec({p.grid_lim, p.grid_lim, p.grid_lim}));
  d += "substep = \"fixed\"\n";
  d += fmt::format("boundary_layers = {}\n", walls ? 3 : 0);
  d += damping;
  if (!walls) notes.push_back("bounding_box: absent, so no grid walls (mpm.boundary_layers = 0)");
  d += fmt::format("\n[output]\nframe_interval = {}\n", num(p.frame_dt));
  return d;
}

//! The keys of a cuboid grid condition.
std::string cuboid_keys(const PhysGaussianParams& p, const PhysGaussianBoundary& b,
                        const std::string& where, double start, Notes& notes) {
  std::string e = fmt::format("velocity = {}\n", vec(b.velocity));
  if (nonzero(b.velocity)) e += "motion = \"moving\"\n";
  if (b.reset == 1) {
    e += fmt::format("reset_duration = {}\n", num(15 * p.substep_dt));
    if (start > 0)
      notes.push_back(
          fmt::format("{}: reset = 1 zeroes the grid for 15 substeps after end_time; "
                      "PhysGaussian also zeroes it before start_time ({}), gen4d does not",
                      where, num(start)));
  }
  return e;
}

//! The force key of a particle_impulse; "" when its box selects no Gaussian.
std::string impulse_keys(const PhysGaussianBoundary& b, const PhysGaussianPreprocessed& pre,
                         const std::string& where, Notes& notes) {
  long count = 0;
  for (std::size_t k = 0; k < pre.selected.size(); ++k) {
    bool in = true;
    for (int a = 0; a < 3; ++a)
      in = in && std::fabs(pre.selected.position[3 * k + a] - b.point[a]) < b.size[a];
    count += in;
  }
  if (count == 0) {
    notes.push_back(fmt::format("{}: particle_impulse selects no Gaussian; left out", where));
    return "";
  }
  notes.push_back(
      fmt::format("{}: particle_impulse force per particle x {} Gaussians in the box = total "
                  "force shared by mass (PhysGaussian: force / m_p on each)",
                  where, count));
  return fmt::format("force = {}\n",
                     vec({b.force[0] * count, b.force[1] * count, b.force[2] * count}));
}

//! The keys of a surface_collider.
std::string collider_keys(const PhysGaussianParams& p, const PhysGaussianBoundary& b,
                          const std::string& where, Notes& notes) {
  const PgVec3 n = normalized(b.normal);
  std::string e = fmt::format("point = {}\n", vec(b.point));
  e += fmt::format("normal = {}\n", vec(n));
  e += fmt::format("surface = {}\n", quoted(b.surface));
  if (b.surface == "cut") {
    // PhysGaussian's hard-coded cut: 0.4 <= z <= 0.53, velocity x 0.3 without its y part.
    e += fmt::format("lo = {}\n", vec({0, 0, 0.4}));
    e += fmt::format("hi = {}\n", vec({p.grid_lim, p.grid_lim, 0.53}));
    e += "cut_scale = 0.3\n";
    if (std::fabs(n[1]) != 1)
      notes.push_back(
          fmt::format("{}: surface \"cut\": gen4d removes the normal velocity {} in the cut "
                      "(0.4 <= z <= 0.53), PhysGaussian the y component",
                      where, vec(n)));
  } else {
    e += fmt::format("friction = {}\n", num(b.friction));
  }
  if (b.surface != "sticky" && b.surface != "cut")
    notes.push_back(
        fmt::format("{}: surface \"{}\" kept as written (PhysGaussian's collider zeroes the "
                    "velocity of every node behind it)",
                    where, b.surface));
  return e;
}

//! The keys of a release_particles_sequentially.
std::string release_keys(const PhysGaussianBoundary& b, const std::string& where, Notes& notes) {
  const int axis = b.normal[0] != 0 ? 0 : b.normal[1] != 0 ? 1 : 2;
  PgVec3 n{0, 0, 0};
  n[axis] = b.end_position > b.start_position ? 1 : -1;
  notes.push_back(
      fmt::format("{}: release over the object's extent along {} in {} layers, layer k at "
                  "start + (end - start) k / layers (PhysGaussian: 50 layers over "
                  "|x - end_position| < |start_position - end_position|, layer i at "
                  "end_time (i + 1) / 50)",
                  where, vec(n), b.num_layers));
  return fmt::format("normal = {}\n", vec(n)) + fmt::format("layers = {}\n", b.num_layers);
}

//! The keys of an enforce_particle_velocity_rotation.
std::string rotation_keys(const PhysGaussianBoundary& b) {
  const PgVec3 n = normalized(b.normal);
  std::string e = fmt::format("point = {}\n", vec(b.point));
  e += fmt::format("normal = {}\n", vec(n));
  e += fmt::format("half_height = {}\n", num(b.half_height_and_radius[0]));
  e += fmt::format("radius = {}\n", num(b.half_height_and_radius[1]));
  e += fmt::format(
      "angular_velocity = {}\n",
      vec({-b.rotation_scale * n[0], -b.rotation_scale * n[1], -b.rotation_scale * n[2]}));
  e += fmt::format("velocity = {}\n", vec({b.translation_scale * n[0], b.translation_scale * n[1],
                                           b.translation_scale * n[2]}));
  return e;
}

//! The [[boundary]] entry of boundary_conditions[i]; "" when it never acts.
std::string boundary_entry(const PhysGaussianParams& p, const PhysGaussianPreprocessed& pre,
                           std::size_t i, Notes& notes) {
  const PhysGaussianBoundary& b = p.boundary_conditions[i];
  const std::string where = fmt::format("boundary_conditions[{}] (line {})", i, b.line);
  double start = std::max(0.0, b.start_time), end = b.end_time;
  if (b.type == "particle_impulse") end = b.start_time + b.num_dt * p.substep_dt;
  if (b.type == "bounding_box") return "\n[[boundary]]\ntype = \"bounding_box\"\n";
  if (!(end > start)) {
    notes.push_back(fmt::format("{}: {} never acts (end {} <= start {}); left out", where, b.type,
                                num(end), num(start)));
    return "";
  }
  std::string e = "\n[[boundary]]\n";
  e += fmt::format("type = {}\n", quoted(b.type));
  if (b.type == "cuboid" || b.type == "particle_impulse" ||
      b.type == "enforce_particle_translation") {
    e += fmt::format("lo = {}\n", vec(add(b.point, b.size, -1)));
    e += fmt::format("hi = {}\n", vec(add(b.point, b.size, 1)));
  }
  if (b.type == "cuboid") e += cuboid_keys(p, b, where, start, notes);
  if (b.type == "enforce_particle_translation")
    e += fmt::format("velocity = {}\n", vec(b.velocity));
  if (b.type == "particle_impulse") {
    const std::string force = impulse_keys(b, pre, where, notes);
    if (force.empty()) return "";
    e += force;
  }
  if (b.type == "surface_collider") e += collider_keys(p, b, where, notes);
  if (b.type == "release_particles_sequentially") e += release_keys(b, where, notes);
  if (b.type == "enforce_particle_velocity_rotation") e += rotation_keys(b);
  e += fmt::format("start = {}\n", num(start));
  e += fmt::format("end = {}\n", num(end));
  return e;
}

//! Every [[boundary]] entry.
std::string deck_boundaries(const PhysGaussianParams& p, const PhysGaussianPreprocessed& pre,
                            Notes& notes) {
  std::string d;
  bool selection_note = false;
  for (std::size_t i = 0; i < p.boundary_conditions.size(); ++i) {
    const std::string e = boundary_entry(p, pre, i, notes);
    if (e.empty()) continue;
    const std::string& type = p.boundary_conditions[i].type;
    if (type == "particle_impulse" || type == "enforce_particle_translation" ||
        type == "enforce_particle_velocity_rotation")
      selection_note = true;
    d += e;
  }
  if (selection_note)
    notes.push_back(
        "particle conditions: PhysGaussian selects their particles once at rest, gen4d at "
        "every substep");
  return d;
}

//! The [render] keys of PhysGaussian's orbit camera, carried to the simulation space.
std::string orbit_keys(const PhysGaussianParams& p, const PhysGaussianSimMap& map,
                       const std::vector<Camera>& cams, Notes& notes) {
  const double s = map.scale;
  const PgVec3 up = normalized(p.mpm_space_vertical_upward_axis);
  // PhysGaussian's frame in the trained space, carried to the simulation space.
  const PgVec3 vw = mat_tvec(map.rotation, up);
  PgVec3 h1{1, 1, 1};
  if (std::fabs(dot(h1, vw)) < 0.01) h1 = {0.72, 0.37, -0.67};
  h1 = normalized(add(h1, vw, -dot(h1, vw)));
  const PgVec3 h1s = mat_vec(map.rotation, h1);
  // gen4d's orbit frame (OrbitCamera::at_frame).
  const PgVec3 a = std::fabs(up[0]) > 0.9 ? PgVec3{0, 1, 0} : PgVec3{1, 0, 0};
  const PgVec3 e1 = normalized(add(a, up, -dot(a, up)));
  const PgVec3 e2 = cross(up, e1);
  const double phi0 = std::atan2(dot(h1s, e2), dot(h1s, e1)) * 180 / kPi;
  double az = phi0 - *p.init_azimuthm, el = *p.init_elevation, rad = s * *p.init_radius;
  double daz = 0, del = 0, drad = 0;
  if (p.move_camera) {
    daz = -*p.delta_a;
    del = *p.delta_e;
    drad = s * *p.delta_r;
    az -= daz;
    el -= del;
    rad -= drad;
  }
  if (!(el > -90 && el < 90))
    fail_key(p, "init_elevation",
             fmt::format("the orbit's elevation {} is outside (-90, 90)", num(el)));
  if (!(rad > 0)) fail_key(p, "init_radius", "the orbit's radius must be > 0");
  std::string r = "camera = \"orbit\"\n";
  r += fmt::format("center = {}\n", vec(p.mpm_space_viewpoint_center));
  r += fmt::format("up = {}\n", vec(p.mpm_space_vertical_upward_axis));
  r += fmt::format("azimuth = {}\n", num(az));
  r += fmt::format("elevation = {}\n", num(el));
  r += fmt::format("radius = {}\n", num(rad));
  if (p.move_camera) {
    r += fmt::format("d_azimuth = {}\n", num(daz));
    r += fmt::format("d_elevation = {}\n", num(del));
    r += fmt::format("d_radius = {}\n", num(drad));
  }
  if (cams.empty()) {
    notes.push_back(
        "camera: PhysGaussian's orbit in the simulation space (its field of view and image "
        "size come from cameras.json, which the model lacks: gen4d's defaults apply)");
    return r;
  }
  // get_camera_view replaces the pose of cameras.json's first entry and keeps the rest.
  const Camera& c0 = cams.front();
  r += fmt::format("width = {}\nheight = {}\n", c0.width, c0.height);
  r += fmt::format("fov_y = {}\n", num(c0.fov_y() * 180 / kPi));
  notes.push_back(fmt::format(
      "camera: PhysGaussian's orbit in the simulation space, with the image size {} x {} and "
      "vertical field of view of cameras.json's first entry",
      c0.width, c0.height));
  if (std::fabs(c0.fx - c0.fy) > 1e-6 * c0.fy)
    notes.push_back(
        fmt::format("camera: cameras.json's fx {} differs from fy {}; gen4d's orbit has "
                    "square pixels (fx = fy)",
                    num(c0.fx), num(c0.fy)));
  return r;
}

//! [render]: gs_simulation.py's images, video rate, scenery and camera.
std::string deck_render(const PhysGaussianParams& p, const PhysGaussianPreprocessed& pre,
                        PlySpace space, const PhysGaussianDeckFiles* files, Notes& notes) {
  std::string r = "\n[render]\nlayout = \"physgaussian\"\nbackground = [0, 0, 0]\n";
  notes.push_back(
      "render: gs_simulation.py's images (OUT/0000.png for the state after one frame, ...; "
      "with --mp4, OUT/output.mp4) on its default black background (--white_bg: set "
      "render.background = [1, 1, 1])");
  const double rate = std::floor(1.0 / p.frame_dt);  // gs_simulation.py: int(1.0 / frame_dt)
  if (rate >= 1 && rate <= 1000)
    r += fmt::format("fps = {}\n", num(rate));
  else
    notes.push_back(
        fmt::format("frame_dt = {}: PhysGaussian's video rate int(1 / frame_dt) = {} is not "
                    "usable; gen4d's default video rate applies",
                    num(p.frame_dt), num(rate)));
  if (space == PlySpace::Simulation && files && !files->scenery_ply.empty() && pre.rest.size())
    r += fmt::format("scenery = {}\n", quoted(files->scenery_ply));
  const std::vector<Camera> no_cameras;
  const std::vector<Camera>& cams = files ? files->cameras : no_cameras;
  if (p.default_camera_index < 0 && p.init_azimuthm && p.init_elevation && p.init_radius)
    return r + orbit_keys(p, pre.map, cams, notes);
  if (p.default_camera_index >= 0 && files && !files->cameras_json.empty() && !cams.empty()) {
    if (static_cast<std::size_t>(p.default_camera_index) >= cams.size())
      fail_key(p, "default_camera_index",
               fmt::format("{} is beyond the model's cameras.json ({} entries)",
                           p.default_camera_index, cams.size()));
    r += fmt::format("camera = {}\n",
                     quoted(fmt::format("{}:{}", files->cameras_json, p.default_camera_index)));
    notes.push_back(fmt::format(
        "default_camera_index = {}: cameras.json's view carried into the simulation space "
        "({}; image size and focal lengths kept). gen4d culls splats nearer than 0.2 to the "
        "camera in simulation units, PhysGaussian in trained units (scale {})",
        p.default_camera_index, files->cameras_json, num(pre.map.scale)));
    return r;
  }
  r += "camera = \"auto\"\n";
  notes.push_back(fmt::format(
      "default_camera_index = {}: {}; the deck's camera frames the object", p.default_camera_index,
      p.default_camera_index >= 0 ? "the model has no cameras.json"
                                  : "init_azimuthm, init_elevation or init_radius missing"));
  return r;
}

}  // namespace

std::string physgaussian_to_deck(const PhysGaussianParams& p, const std::string& ply_path,
                                 const PhysGaussianPreprocessed& pre, PlySpace space,
                                 std::vector<std::string>* notes_out,
                                 const PhysGaussianDeckFiles* files) {
  if (p.frame_num < 1) fail_key(p, "frame_num", "must be >= 1 for a run (nothing to simulate)");
  Notes notes;
  std::string d = deck_object(p, ply_path, pre, space, files, notes);
  d += deck_materials(p, notes);
  const std::string damping = deck_damping(p, notes);
  note_filling(p, notes);
  d += deck_solver(p, damping, notes);
  d += deck_boundaries(p, pre, notes);
  d += deck_render(p, pre, space, files, notes);
  if (p.show_hint) notes.push_back("show_hint: PhysGaussian prints the camera and exits; ignored");
  if (notes_out) *notes_out = std::move(notes);
  return d;
}

}  // namespace gen4d::gaussians
