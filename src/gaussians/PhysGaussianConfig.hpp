//! PhysGaussian's JSON scene configs (config/*.json of Xie et al.'s release, read by
//! gs_simulation.py through utils/decode_param.py): read exactly, preprocessed as
//! gs_simulation.py does, and converted to an equivalent gen4d deck (PhysGaussianConfig.cpp
//! documents every mapping and difference).
#pragma once

#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "gaussians/Camera.hpp"
#include "gaussians/Splats.hpp"

namespace gen4d::gaussians {

using PgVec3 = std::array<double, 3>;

//! One entry of additional_material_params: particles strictly inside the box
//! |x - point| < size (size is the half extent) take their own E, nu and density.
struct PhysGaussianMaterialBox {
  PgVec3 point{0, 0, 0};
  PgVec3 size{0, 0, 0};
  double E = 0;
  double nu = 0;
  double density = 0;  //!< the config's global density when the entry leaves it out
  int line = 0;        //!< line of the entry in the file
};

//! One entry of boundary_conditions. Only the fields of its type are meaningful; each holds
//! the value PhysGaussian uses when the key is absent (set_boundary_conditions).
struct PhysGaussianBoundary {
  std::string type;  //!< cuboid | particle_impulse | bounding_box | enforce_particle_translation
                     //!< | surface_collider | release_particles_sequentially
                     //!< | enforce_particle_velocity_rotation
  int line = 0;      //!< line of the entry in the file
  PgVec3 point{1, 1, 1};  //!< box centre, plane point or cylinder centre
  PgVec3 size{1, 1, 1};   //!< box half extent
  PgVec3 velocity{0, 0, 0};
  PgVec3 force{0, 0, 0};   //!< particle_impulse: force on each selected particle
  PgVec3 normal{0, 0, 1};  //!< as written (not normalised)
  double start_time = 0;
  double end_time = 1e3;  //!< cuboid's default; required by the other timed types
  int reset = 0;          //!< cuboid: 1 zeroes the whole grid for 15 substeps after end_time
  int num_dt = 1;         //!< particle_impulse: substeps the impulse lasts
  std::string surface = "sticky";  //!< surface_collider: sticky | slip | separate | cut
  double friction = 0;
  double start_position = 0, end_position = 0;  //!< release_particles_sequentially
  int num_layers = 0;
  std::array<double, 2> half_height_and_radius{0, 0};  //!< enforce_particle_velocity_rotation
  double rotation_scale = 0;     //!< rad/s about the axis (see the .cpp for its sense)
  double translation_scale = 0;  //!< m/s along the axis
};

//! particle_filling (internal particle filling of a shell of surface Gaussians).
struct PhysGaussianFilling {
  int n_grid = 0;  //!< default 4 n_grid
  double density_threshold = 5.0;
  double search_threshold = 3.0;
  long max_particles_num = 2000000;
  //! From max_partciels_per_cell (PhysGaussian's spelling, the key it reads) or
  //! max_particles_per_cell; at most one of them may be given.
  int max_particles_per_cell = 1;
  int search_exclude_direction = 5;
  int ray_cast_direction = 4;
  std::optional<std::array<double, 6>> boundary;  //!< x0, x1, y0, y1, z0, z1; null: none
  bool smooth = false;
  bool visualize = false;
};

//! Every key decode_param.py reads, with its default.
struct PhysGaussianParams {
  std::string source;  //!< the file read
  // material_params
  std::string material = "jelly";  //!< jelly | metal | sand | foam | snow | plasticine
  double grid_lim = 2.0;
  int n_grid = 50;
  double E = 1e5;
  double nu = 0.4;
  double density = 200.0;
  //! decode_param's default is the scalar 9.8, which PhysGaussian's solver cannot index (it
  //! stops with a TypeError); absent, gen4d takes 9.8 downwards along -z.
  PgVec3 g{0, 0, -9.8};
  bool has_g = false;
  // Solver values whose defaults come from MPM_Simulator_WARP when the key is absent.
  double yield_stress = 0;
  bool has_yield_stress = false;
  int hardening = 0;  //!< 1 switches hardening on (any other value: off)
  double xi = 0;
  double friction_angle = 25.0;  //!< degrees
  double plastic_viscosity = 0;
  double softening = 0.1;
  double rpic_damping = 0;
  std::optional<double> pic_damping;  //!< read by decode_param, used by no solver code
  double grid_v_damping_scale = 1.1;  //!< < 1 damps the grid velocities every substep
  std::vector<PhysGaussianMaterialBox> additional_material_params;
  std::vector<PhysGaussianBoundary> boundary_conditions;
  // time_params
  double substep_dt = 1e-4;
  double frame_dt = 1e-2;
  int frame_num = 100;
  // preprocessing_params
  double opacity_threshold = 0.02;
  std::vector<double> rotation_degree;            //!< degrees, applied in list order
  std::vector<int> rotation_axis;                 //!< 0 x, 1 y, 2 z
  std::optional<std::array<double, 6>> sim_area;  //!< x0, x1, y0, y1, z0, z1 (after rotation)
  double scale = 1.0;  //!< longest side of the selection in simulation space
  std::optional<PhysGaussianFilling> particle_filling;
  // camera_params
  PgVec3 mpm_space_viewpoint_center{1, 1, 1};
  PgVec3 mpm_space_vertical_upward_axis{0, 0, 1};
  int default_camera_index = 0;  //!< >= 0: that entry of the model's cameras.json
  bool show_hint = false;
  std::optional<double> init_azimuthm, init_elevation, init_radius;  //!< degrees, world units
  bool move_camera = false;
  std::optional<double> delta_a, delta_e, delta_r;  //!< per rendered frame
};

//! Reads a PhysGaussian config. InputError "FILE:LINE: key 'K': ..." for malformed JSON, an
//! unknown key, a wrong type, and the values PhysGaussian itself rejects (nu outside [0, 0.5],
//! an unknown material or boundary type, a missing required boundary key, rotation lists of
//! different lengths or an axis outside 0..2, a sim_area without 6 numbers, friction on a
//! sticky surface), plus values that cannot describe a run (non-positive grid_lim, n_grid,
//! substep_dt, frame_dt, scale; a zero normal).
PhysGaussianParams read_physgaussian_config(const std::string& path);

//! PhysGaussian's map between the trained object's space (world) and the simulation space:
//! sim = scale (R world - center) + (1, 1, 1).
struct PhysGaussianSimMap {
  std::array<double, 9> rotation{1, 0, 0, 0, 1, 0, 0, 0, 1};  //!< R, row-major
  double scale = 1;
  PgVec3 center{0, 0, 0};  //!< centre of the rotated selection's bounding box (world units)
  PgVec3 to_sim(const PgVec3& world) const;
  PgVec3 to_world(const PgVec3& sim) const;
  //! The translation t of sim = scale R world + t.
  PgVec3 translation() const;
};

//! The composite rotation of rotation_degree / rotation_axis (applied in list order: the
//! matrix of the last entry multiplies last). Exact pi (PhysGaussian uses 3.1415926).
std::array<double, 9> physgaussian_rotation(const PhysGaussianParams& params);

//! What gs_simulation.py makes of a trained object before simulating it.
struct PhysGaussianPreprocessed {
  SplatSet selected;  //!< the simulated Gaussians, in simulation space
  //! Gaussians that passed the opacity filter but lie outside sim_area, mapped to simulation
  //! space by the same map (static scenery rendered with the selection).
  SplatSet rest;
  PhysGaussianSimMap map;
  std::vector<std::size_t> selected_index;  //!< indices into the trained set
  std::vector<std::size_t> rest_index;
};

//! gs_simulation.py's preprocessing: keeps the Gaussians with opacity > opacity_threshold,
//! rotates them by physgaussian_rotation, keeps those strictly inside sim_area (when given),
//! then scales the selection so that the longest side of its bounding box becomes `scale` and
//! centres that box at (1, 1, 1). Positions, covariances (via orientations and scales) and
//! harmonics all transform (transform_splats). InputError naming params.source when nothing
//! is selected or the selection has no extent.
PhysGaussianPreprocessed preprocess_physgaussian(const SplatSet& trained,
                                                 const PhysGaussianParams& params);

//! How physgaussian_to_deck refers to the object's PLY.
enum class PlySpace {
  Trained,     //!< ply_path is the trained file: the deck applies the map (no sim_area crop)
  Simulation,  //!< ply_path holds PhysGaussianPreprocessed::selected (crop and map applied)
};

//! Files beside the deck that it refers to (paths as the deck writes them, relative to its
//! folder), and the model's cameras.
struct PhysGaussianDeckFiles {
  //! "" or pre.rest written in simulation space (PlySpace::Simulation only): [render] scenery.
  std::string scenery_ply;
  //! "" or the model's cameras.json mapped to simulation space (cameras_to_simulation).
  std::string cameras_json;
  //! The model's cameras.json entries (trained space); empty when the model has none.
  std::vector<Camera> cameras;
};

//! The equivalent gen4d deck (TOML text, solver.method = "mpm") for running the object of
//! `pre` (from preprocess_physgaussian of the same params) stored at ply_path. `notes`, when
//! given, receives one line per mapping decision, per behaviour of PhysGaussian that gen4d
//! does differently, and per key gen4d cannot honour yet. `files`, when given, adds the
//! scenery outside sim_area, the view of default_camera_index >= 0 and cameras.json's image
//! size and field of view for the orbit. InputError for a config gen4d cannot run at all
//! (frame_num < 1, elevations outside (-90, 90), default_camera_index beyond the cameras).
std::string physgaussian_to_deck(const PhysGaussianParams& params, const std::string& ply_path,
                                 const PhysGaussianPreprocessed& pre, PlySpace space,
                                 std::vector<std::string>* notes = nullptr,
                                 const PhysGaussianDeckFiles* files = nullptr);

}  // namespace gen4d::gaussians
