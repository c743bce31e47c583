//! Typed, validated contents of a deck (see inputs/README.md for every key).
#pragma once

#include <algorithm>
#include <array>
#include <map>
#include <string>
#include <vector>

#include "core/Curve.hpp"

namespace gen4d {

using Vec3d = std::array<double, 3>;

//! Axis-aligned box region [lo, hi] in metres.
struct BoxRegion {
  Vec3d lo{0, 0, 0};
  Vec3d hi{0, 0, 0};
  bool contains(const Vec3d& p) const {
    for (int d = 0; d < 3; ++d)
      if (p[d] < lo[d] || p[d] > hi[d]) return false;
    return true;
  }
};

//! One solid in the union that makes up the object.
struct GeometryConfig {
  //! "box" | "sphere" | "capsule" | "cylinder" | "mesh" | "vdb" | "splats"
  std::string type;
  std::string name;  //!< optional, unique; what a [[material]] entry's `geometry` refers to
  // box
  Vec3d lo{0, 0, 0}, hi{0, 0, 0};
  // sphere
  Vec3d center{0, 0, 0};
  double radius = 0;
  // capsule: points within radius of the segment a-b; cylinder: the flat-ended cylinder with
  // axis a-b and that radius
  Vec3d a{0, 0, 0}, b{0, 0, 0};
  // mesh / vdb: file path (resolved relative to the deck's folder), transform
  std::string file;
  std::string grid;  //!< vdb grid name; empty = first level-set grid
  double scale = 1.0;
  Vec3d translate{0, 0, 0};
  // splats (a 3DGS PLY in `file`): the transform maps a splat's position p to
  // scale * R p + translate, with R the rotation by rotate_degrees about rotate_axis; Gaussians
  // whose opacity is below opacity_threshold are dropped (PhysGaussian's 0.02 by default).
  Vec3d rotate_axis{0, 0, 1};
  double rotate_degrees = 0;
  double opacity_threshold = 0.02;
  //! > 0: the interior of the splat object is filled with particles (PhysGaussian's internal
  //! filling, gaussians/Filling.hpp) on a grid of this many cells along its longest side.
  int fill_cells = 0;
  //! Colour (linear RGB in [0, 1]) of the splats made from a non-splat part for rendering.
  Vec3d color{0.75, 0.75, 0.75};
};

struct MaterialConfig {
  std::string model = "corotated";  //!< registered material name
  std::string target = "arap";      //!< "arap" (p = R) | "analytic" (p = F - P/k) | "neural"
  //! NeuralMTL weight file for target "neural" (absolute); empty: generated from the law and nu
  std::string neural_weights;
  double youngs_modulus = 0;  //!< Pa
  double poisson_ratio = 0;   //!< (-1, 0.5)
  double density = 0;         //!< kg/m^3
  //! solver.method = "mpm": the model's further keys (yield_stress, friction_angle, ...) and
  //! where each was set ("FILE:LINE" or "--set ..."), checked by the MPM material registry.
  std::map<std::string, double> params;
  std::map<std::string, std::string> param_where;
  // Binding of a [[material]] entry after the first: the part named `geometry` (its index in
  // Config::geometry is `geometry_part`), or the rest positions inside `region`.
  std::string geometry;
  int geometry_part = -1;
  bool has_region = false;
  BoxRegion region;
  std::string where;  //!< "FILE:LINE" of the entry, for messages
};

struct SolverConfig {
  std::string method = "elastogen";   //!< "elastogen" | "newton" (reference) | "mpm"
  std::string relaxation = "jacobi";  //!< "jacobi" | "chebyshev" | "cg"
  double jacobi_omega = 0.67;         //!< damping of Jacobi sweeps, (0, 1]
  double chebyshev_ratio = 0.05;      //!< lambda_min / lambda_max of the Chebyshev interval
  int max_sweeps = 100;               //!< per outer loop
  double inner_tolerance = 1e-3;      //!< relative residual of the global step
  int subspace_modes = 18;            //!< K low-frequency modes; 0 disables
  int max_outer = 10;                 //!< RNN-1 loops per step
  double outer_tolerance = 1e-3;      //!< relative change of x between loops
  double accuracy_tolerance = 1e-3;   //!< relative true residual after the loops
  int max_extra_outer = 100;          //!< extra loops allowed by the accuracy check
  int anderson_depth = 5;             //!< Anderson acceleration history of RNN-1; 0 disables
};

//! [mpm]: the material point method's grid, particles and substeps (solver.method = "mpm").
struct MpmConfig {
  bool has_box = false;        //!< lo/hi given; else the object's bounds plus domain.padding cells
  Vec3d lo{0, 0, 0};           //!< m, grid box
  Vec3d hi{0, 0, 0};           //!< m
  int particles_per_axis = 2;  //!< per cell and axis (2 -> 8 particles per cell)
  double cfl = 0.3;            //!< substep <= cfl * dx / max particle speed
  double wave_cfl = 0.5;       //!< substep <= wave_cfl * dx / elastic wave speed
  std::string substep = "adaptive";     //!< "adaptive" | "fixed" (always simulation.dt)
  std::string out_of_domain = "clamp";  //!< "clamp" | "remove"
  int boundary_layers = 3;              //!< grid layers of the bounding_box condition
  Vec3d velocity{0, 0, 0};              //!< initial velocity of every particle, m/s
  double max_cells_per_substep =
      1.0;  //!< instability guard: a particle moving farther stops the run
  //! P2G's affine matrix C -> (1 - r) C + r skew(C) for r in [0, 1] (PhysGaussian's RPIC
  //! damping; 0: APIC); -1: PIC (C = 0).
  double rpic_damping = 0;
  double grid_velocity_scale = 1;  //!< grid velocities times this every substep; 1: off
};

//! [[boundary]] of the MPM solver, as in PhysGaussian's configs; active for start <= t < end.
struct BoundaryConfig {
  std::string type;  //!< bounding_box | cuboid | particle_impulse | enforce_particle_translation
                     //!< | enforce_particle_velocity_rotation | surface_collider
                     //!< | release_particles_sequentially
  BoxRegion region;  //!< lo/hi (cuboid, impulse, translation, the cut of a "cut" collider)
  Vec3d point{0, 0, 0};
  Vec3d normal{0, 0, 1};
  Vec3d velocity{0, 0, 0};
  Vec3d angular_velocity{0, 0, 0};     //!< rad/s about `point` (velocity_rotation)
  Vec3d force{0, 0, 0};                //!< N, total over the region's particles (impulse)
  double radius = 0, half_height = 0;  //!< cylinder of velocity_rotation (axis = normal)
  std::string surface = "sticky";      //!< surface_collider: sticky | slip | separate | cut
  double friction = 0;
  //! cuboid: "fixed" (the box stays at lo/hi) or "moving" (it translates with `velocity` while
  //! active: lo/hi + velocity (clamp(t, start, end) - start)).
  std::string motion = "fixed";
  //! cuboid: for this long after `end` (s) every grid velocity is zeroed; 0: never.
  double reset_duration = 0;
  //! surface_collider "cut": nodes behind the plane and inside `region` (the cut) lose their
  //! normal velocity and keep this fraction of the rest; the other nodes behind it stop.
  double cut_scale = 0.3;
  //! surface_collider: nodes up to this far outside the plane (m) are blended in, with weight
  //! 1 - distance / width, so the collider's action is continuous in its position (diagnose
  //! fits a plane's height); 0, as decks give it: only nodes on or inside the plane.
  double soft_width = 0;
  int layers = 1;  //!< release_particles_sequentially
  double start = 0;
  double end = 1e300;
  //! Time factor ([[curve]]) of a cuboid's or a particle condition's velocity, force and
  //! angular velocity; a moving cuboid travels velocity times the curve's integral. Empty: 1.
  Curve curve;
};

struct FixedConfig {
  BoxRegion region;  //!< nodes inside are held at their rest positions
};

//! Nodes inside move on a prescribed rigid path: rotation by angular_velocity * tau about an
//! axis through `center`, plus velocity * tau, with tau = clamp(t, start, end) - start.
struct KinematicConfig {
  BoxRegion region;
  Vec3d center{0, 0, 0};            //!< m, a point on the rotation axis
  Vec3d velocity{0, 0, 0};          //!< m/s
  Vec3d angular_velocity{0, 0, 0};  //!< rad/s (axis direction times rate)
  double start = 0;                 //!< s
  double end = 1e300;               //!< s; the region holds its last pose afterwards
  //! [[curve]] scaling both rates: tau becomes the curve's integral over [start, clamp(t)].
  Curve curve;
};

struct ForceConfig {
  BoxRegion region;      //!< nodes inside share the force, by mass
  Vec3d force{0, 0, 0};  //!< total force in newtons
  //! s; start < 0: a pre-load, applied before the run begins: the body starts at rest in its
  //! static equilibrium under the pre-loads (released at `end`, e.g. 0 for a pluck).
  double start = 0;
  double end = 1e300;  //!< s (exclusive)
  Curve curve;         //!< time factor of `force` ([[curve]]); empty: 1
};

//! [[point_mass]] (alias [[attached_mass]]): a rigid part of `mass` kg glued to the body over
//! the reference positions in `region` (a face patch or a volume): a sensor board, a bolted box.
//! The voxel solvers add it to the nodes in the region, the MPM solver to the particles in it,
//! in proportion to their own mass, so it moves with them and gravity pulls on it.
struct PointMassConfig {
  BoxRegion region;
  double mass = 0;    //!< kg
  std::string where;  //!< "FILE:LINE" of the entry, for messages
};

//! A static rigid obstacle the object cannot enter, with Coulomb friction on contact.
struct ColliderConfig {
  std::string type;       //!< "plane" | "box"
  Vec3d point{0, 0, 0};   //!< plane: a point on it
  Vec3d normal{0, 0, 1};  //!< plane: normal towards the allowed side (any length > 0)
  BoxRegion box;          //!< box: the object is kept outside [lo, hi]
  double friction = 0.5;  //!< Coulomb coefficient mu >= 0
};

//! A surface load on the object's boundary faces whose centre lies in `region`, fixed in the
//! reference configuration (dead load), applied for start <= t < end.
struct TractionConfig {
  BoxRegion region;
  Vec3d traction{0, 0, 0};  //!< Pa (N per m^2 of reference face)
  double pressure = 0;      //!< Pa, along the inward reference normal (positive pushes in)
  double start = 0;         //!< s
  double end = 1e300;       //!< s (exclusive)
  Curve curve;              //!< time factor of traction and pressure ([[curve]]); empty: 1
};

struct OutputConfig {
  std::string dir = "gen4d-out";
  double frame_interval = 0;  //!< s; 0 = every step
  int checkpoint_every = 0;   //!< steps; 0 = only at the end and on signals
  int checkpoint_keep = 2;
  double progress_interval = 2.0;  //!< wall seconds between progress lines
  //! Per-frame surface files, "none" | "ply" | "obj", of "auto" | "mesh" | "voxels".
  std::string surface = "none";
  std::string surface_source = "auto";
  //! MPM: per-frame particle point clouds "none" | "ply", and OpenVDB volumes "none" | "vdb"
  //! (density and velocity grids).
  std::string particles = "none";
  std::string volumes = "none";
};

//! [render]: images of the splats of a run (a deck's splat geometry, or splats made from its
//! other geometry), one PNG per output frame under OUT/png/, optionally an MP4.
struct RenderConfig {
  bool enabled = false;          //!< the deck has a [render] table
  std::string camera = "orbit";  //!< "orbit" | a 3DGS cameras.json "FILE[:INDEX]" (resolved)
  // orbit camera (gaussians::OrbitCamera): degrees, world units; d_* per output frame
  Vec3d center{0, 0, 0};
  Vec3d up{0, 0, 1};
  double azimuth = 0, elevation = 20, radius = 1;
  double d_azimuth = 0, d_elevation = 0, d_radius = 0;
  double fov_y = 45;  //!< degrees
  int width = 640, height = 480;
  Vec3d background{1, 1, 1};  //!< colour channels in [0, 1]
  //! "full" | "fixed_covariance" | "rigid_covariance" | "fixed_harmonics" (seed's ablations)
  std::string kinematics = "full";
  //! MPM: "deformation_gradient" (a = F A0 F^T) | "rate" (a += dt (L a + a L^T))
  std::string covariance_update = "deformation_gradient";
  //! Spacing of the splats made from non-splat geometry; 0: the particle or voxel spacing.
  double splat_spacing = 0;
  bool mp4 = false;  //!< assemble the images into a video where ffmpeg exists
  //! "gen4d": OUT/png/frame_NNNNNN.png for every output frame, video OUT/render.mp4;
  //! "physgaussian": gs_simulation.py's OUT/0000.png, 0001.png, ... for output frames 1, 2, ...
  //! (no image of frame 0, the rest state), video OUT/output.mp4.
  std::string layout = "gen4d";
  double fps = 0;  //!< the video's frame rate; 0: 1 / frame interval, within [1, 60]
  //! "" or a 3DGS PLY (absolute path) drawn unmoved, as it is in the file, in every frame.
  std::string scenery;
};

struct Config {
  // [simulation]
  std::string name = "gen4d";
  double dt = 0;        //!< s
  double end_time = 0;  //!< s
  Vec3d gravity{0, 0, -9.81};
  // [domain]
  //! Cell edges along x, y, z, m (domain.voxel_size: one number for cubes, or [hx, hy, hz]).
  //! The voxel solvers (ElastoGen, Newton, diagnose's model) take any three; the MPM solver
  //! takes cubes only (the deck reader refuses others).
  Vec3d spacing{0, 0, 0};
  //! The largest of the cell edges (every edge when the cells are cubes), m.
  double voxel_size = 0;
  bool cubic_cells() const { return spacing[0] == spacing[1] && spacing[1] == spacing[2]; }
  //! The cell edges to use: `spacing`, or, where code has set voxel_size alone since the deck
  //! was read (a refined copy), cubes of voxel_size (cubic or unset spacing) or the spacing
  //! scaled so that its largest edge is voxel_size.
  Vec3d cell_edges() const {
    const double largest = std::max({spacing[0], spacing[1], spacing[2]});
    if (largest == voxel_size) return spacing;
    if (!(largest > 0) || cubic_cells()) return {voxel_size, voxel_size, voxel_size};
    const double f = voxel_size / largest;
    return {spacing[0] * f, spacing[1] * f, spacing[2] * f};
  }
  int padding = 1;  //!< empty voxels around the object's bounds
  std::vector<GeometryConfig> geometry;
  //! [material], or the first [[material]]: the material of everything no later entry claims.
  MaterialConfig material;
  //! The [[material]] entries after the first, in deck order; a particle or voxel takes the last
  //! one whose binding holds it (material_slot).
  std::vector<MaterialConfig> material_regions;
  SolverConfig solver;
  std::vector<FixedConfig> fixed;
  std::vector<KinematicConfig> kinematic;
  std::vector<ForceConfig> forces;
  std::vector<PointMassConfig> point_masses;
  std::vector<ColliderConfig> colliders;
  std::vector<TractionConfig> tractions;
  MpmConfig mpm;
  std::vector<BoundaryConfig> boundaries;
  OutputConfig output;
  RenderConfig render;
  std::vector<Curve> curves;  //!< [[curve]] tables, in deck order

  //! Where each table and key of the deck was given, "FILE:LINE" or "--set KEY=VALUE", keyed
  //! "table" and "table.key" (an array table: its first element holding the key); what
  //! check_deck_use (core/DeckUse.hpp) points at.
  std::map<std::string, std::string> where;

  std::string source;  //!< deck path ("<embedded>" for built-in text)
  std::string text;    //!< final deck text (TOML, overrides applied); stored in outputs
};

//! Material slot of a point of geometry part `part` (index in Config::geometry, -1 when
//! unknown) at rest position x: 1 + the index of the last material_regions entry whose binding
//! holds it, else 0 (Config::material).
inline int material_slot(const Config& c, int part, const Vec3d& x) {
  for (int k = static_cast<int>(c.material_regions.size()) - 1; k >= 0; --k) {
    const MaterialConfig& m = c.material_regions[static_cast<std::size_t>(k)];
    if (m.has_region ? m.region.contains(x) : (part >= 0 && part == m.geometry_part)) return k + 1;
  }
  return 0;
}

//! The material of slot s (0: Config::material, k: material_regions[k - 1]).
inline const MaterialConfig& material_of_slot(const Config& c, int s) {
  return s == 0 ? c.material : c.material_regions.at(static_cast<std::size_t>(s - 1));
}

}  // namespace gen4d
