//! Typed, validated contents of a deck (see inputs/README.md for every key).
#pragma once

#include <array>
#include <string>
#include <vector>

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
  std::string type;  //!< "box" | "sphere" | "capsule" | "mesh" | "vdb"
  // box
  Vec3d lo{0, 0, 0}, hi{0, 0, 0};
  // sphere
  Vec3d center{0, 0, 0};
  double radius = 0;
  // capsule: segment a-b with radius
  Vec3d a{0, 0, 0}, b{0, 0, 0};
  // mesh / vdb: file path (resolved relative to the deck's folder), transform
  std::string file;
  std::string grid;  //!< vdb grid name; empty = first level-set grid
  double scale = 1.0;
  Vec3d translate{0, 0, 0};
};

struct MaterialConfig {
  std::string model = "corotated";  //!< registered material name
  std::string target = "arap";      //!< "arap" (p = R) | "analytic" (p = F - P/k) | "neural"
  //! NeuralMTL weight file for target "neural" (absolute); empty: generated from the law and nu
  std::string neural_weights;
  double youngs_modulus = 0;  //!< Pa
  double poisson_ratio = 0;   //!< (-1, 0.5)
  double density = 0;         //!< kg/m^3
};

struct SolverConfig {
  std::string method = "elastogen";   //!< "elastogen" | "newton" (reference solver)
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
};

struct ForceConfig {
  BoxRegion region;      //!< nodes inside share the force, by mass
  Vec3d force{0, 0, 0};  //!< total force in newtons
  double start = 0;      //!< s
  double end = 1e300;    //!< s (exclusive)
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
};

struct Config {
  // [simulation]
  std::string name = "gen4d";
  double dt = 0;        //!< s
  double end_time = 0;  //!< s
  Vec3d gravity{0, 0, -9.81};
  // [domain]
  double voxel_size = 0;  //!< m
  int padding = 1;        //!< empty voxels around the object's bounds
  std::vector<GeometryConfig> geometry;
  MaterialConfig material;
  SolverConfig solver;
  std::vector<FixedConfig> fixed;
  std::vector<KinematicConfig> kinematic;
  std::vector<ForceConfig> forces;
  std::vector<ColliderConfig> colliders;
  std::vector<TractionConfig> tractions;
  OutputConfig output;

  std::string source;  //!< deck path ("<embedded>" for built-in text)
  std::string text;    //!< final deck text (TOML, overrides applied); stored in outputs
};

}  // namespace gen4d
