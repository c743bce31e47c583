//! The forward model of `gen4d diagnose`: the deck's voxelized body as hexahedra on the
//! ElastoGen voxels (2x2x2 Gauss points, the deck's material law) enriched by Wilson-Taylor
//! incompatible modes, with a half-consistent mass matrix, integrated by the trapezoidal rule
//! (Newmark beta = 1/4, gamma = 1/2), which adds no numerical damping, so measured decay is
//! physics. The enrichment and the mass matter against real data: with ElastoGen's plain
//! trilinear voxels and lumped masses a 20x4x4 cantilever calibrated E 3.5 % low against
//! CalculiX C3D20R (0.4 % with both) and its higher modes drifted out of phase.
//! Every effect of the library is a term of this model that vanishes at its null value. One
//! run is serial; diagnose spreads runs over ranks.
#pragma once

#include <algorithm>
#include <array>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/SparseCore>

#include "core/Config.hpp"
#include "forward/Terms.hpp"

namespace gen4d::forward {

//! The voxel element: trilinear hexahedron with 2x2x2 Gauss points (ElastoGen's), or the same
//! with Wilson-Taylor incompatible modes (three bubbles per voxel, condensed per element),
//! which removes the trilinear element's shear locking in bending.
enum class Element { trilinear, incompatible };

//! One effect in a forward run: the values of its terms (TermSource::add_terms reads them).
struct AppliedEffect {
  const TermSource* effect = nullptr;
  std::vector<double> terms;
};

//! The physics of one forward run: the deck's values plus the applied effects.
struct Physics {
  Element element = Element::incompatible;
  //! Mass matrix: this fraction consistent (trilinear shape functions), the rest lumped. The
  //! mean of the two cancels most of either's dispersion error (lumped masses lower the
  //! frequencies of the higher modes, consistent ones raise them): against CalculiX C3D20R
  //! on a 20x4x4 cantilever, 2 s, chi2 per sample 1.70 (lumped), 2.11 (consistent), 1.47 (0.5).
  double consistent_mass_fraction = 0.5;
  std::string law;  //!< hyperelastic law: corotated | neo_hookean | stvk
  double youngs_modulus = 0, poisson_ratio = 0, density = 0;
  Vec3d gravity{0, 0, 0};
  double dt = 0;
  //! The effects applied on top of the deck's physics (Effect::apply), one entry per effect,
  //! in library order; an effect at its null values has none.
  std::vector<AppliedEffect> effects;
  //! Multiplies the deck's [[force]] loads (to design a separating experiment, or fit a
  //! pre-load of unknown size).
  double load_scale = 1;
  //! The model's time at the recording's t = 0 (s): a sample at t is the model's state at
  //! t + time_offset; before the model's t = 0 the body is at rest in its initial state (a
  //! release time known to a few milliseconds). Voxel decks.
  double time_offset = 0;
  //! Pre-loads are removed over this long after their end (s), as 1/2 (1 + cos(pi s / this)):
  //! a hand lets go over milliseconds, and an instant release would ring every mode of the
  //! mesh, which the trapezoidal rule never damps. 0: at once.
  double release_duration = 0;
  //! The recording's zero-phase low-pass cutoff (Hz; 0: none): the run's motion at its steps
  //! is filtered alike (Filter.hpp) before it is sampled, so nothing above the cutoff aliases
  //! into the samples. Voxel decks.
  double lowpass_hz = 0;
  //! A step's Newton iteration stops at a correction below this many voxel sizes (every node
  //! and bubble amplitude): 1e-5 keeps a fit's finite differences (1e-3 to 1e-2 relative
  //! parameter steps) clean of the iteration's own error.
  double newton_tolerance = 1e-5;
  //! The lagged tangent is rebuilt when an iteration's correction shrinks by less than this
  //! factor (from the third iteration on). A rebuild costs ~27 iterations on the 20x4x4 beam
  //! and ~150 on its h/2 model, whose factorization dominates a run.
  double refresh_contraction = 0.5;
  //! A linear problem (the linear law; no plasticity, viscoelasticity, contact or node forces)
  //! takes one solve a step: its step matrix is its exact tangent, so the first correction is
  //! the step's solution up to rounding and a second iteration would only confirm it. false:
  //! iterate to the tolerance anyway (tests compare the two).
  bool linear_single_solve = true;
};

//! A point attached to the body: the voxel containing it and trilinear weights of its nodes.
struct Attachment {
  std::array<int, 8> node{};  //!< compact node ids
  std::array<double, 8> w{};
  Vec3d X{0, 0, 0};  //!< the reference point itself (the MPM model attaches from it)
};

//! What to sample: one attachment per channel, its kind and sample times.
struct ChannelRequest {
  Attachment at;
  bool acceleration = false;  //!< false: position x; true: acceleration
  std::vector<double> t;
};

//! Result of a run: per channel, 3 values per sample (x, y, z), in request order.
struct Trace {
  std::vector<std::vector<double>> channel;
  bool ok = true;        //!< false when a step failed to converge or went non-finite
  std::string failure;   //!< why, for the log
  double max_speed = 0;  //!< over nodes and steps, m/s
  double max_mises = 0;  //!< largest von Mises (Kirchhoff) stress seen, Pa
  long steps = 0;
  long newton_iterations = 0;
  long factorizations = 0;
  long restarts = 0;  //!< steps whose lagged-tangent Newton diverged and were redone
  //! StVK: Gauss points whose stress was continued below kStvkContinuedStretch (or that were
  //! inverted), counted once per step at its predictor (the pass that also takes the step's
  //! von Mises stress); 0 for the other laws.
  long continued_points = 0;
  //! Wall seconds by phase: internal forces, tangent assembly, factorization, back-substitution.
  double time_internal = 0, time_tangent = 0, time_factor = 0, time_solve = 0;
};

//! What `gen4d diagnose` needs of a forward model: the body's cells (reference coordinates on
//! a regular grid of size h), attaching points to it, and runs of a Physics to sampled traces.
//! Implemented by the voxel elastodynamics model (VoxelModel) and by the MPM solver (MpmModel).
class ForwardModel {
 public:
  virtual ~ForwardModel() = default;
  virtual const Config& config() const = 0;
  //! "voxel" or "mpm", for the reports.
  virtual std::string kind() const = 0;
  //! The deck's physics at its nominal values (no effect).
  virtual Physics nominal() const = 0;
  //! The largest cell edge (m) and the solid cells of the body at rest.
  virtual double h() const = 0;
  virtual std::size_t voxels() const = 0;
  virtual Vec3d voxel_center(std::size_t v) const = 0;
  virtual const std::array<long, 3>& voxel_ijk(std::size_t v) const = 0;
  virtual BoxRegion voxel_box(const std::vector<std::size_t>& voxels) const = 0;
  virtual BoxRegion bounds() const = 0;
  //! Volume of the solid cells (m^3) and their exposed surface area (m^2, clamps excluded).
  virtual double volume() const = 0;
  virtual double exposed_area() const = 0;
  //! True when X lies in the body (within a quarter cell).
  virtual bool inside(const Vec3d& X) const = 0;
  //! Attachment of X (call inside() first).
  virtual Attachment attach(const Vec3d& X) const = 0;
  //! Times where the load program switches, sorted, unique.
  virtual std::vector<double> load_events() const = 0;
  //! Runs the model from rest to the last requested time.
  virtual Trace run(const Physics& phys, const std::vector<ChannelRequest>& req) const = 0;
  //! Lowest rest angular frequency with a component along `direction`; NaN where the model
  //! has none to offer.
  virtual double rest_frequency(const Physics& phys, const Vec3d& direction) const = 0;
  //! Whether the model represents `effect` (in `variant`, empty: any) for this deck; the
  //! effects it does not are left out of the library with the reason `unsupported_reason`.
  virtual bool models(const std::string& /*effect*/, const std::string& /*variant*/) const {
    return true;
  }
  virtual std::string unsupported_reason(const std::string& /*effect*/) const { return {}; }
  //! Whether accelerometer channels can be sampled.
  virtual bool samples_accelerations() const { return true; }
};

//! What ph's applied effects add to a run (each one's add_terms, in ph.effects order).
ModelTerms model_terms(const Physics& ph);

//! The forward model of a deck: MpmModel for solver.method = "mpm", else VoxelModel.
std::unique_ptr<ForwardModel> make_forward_model(const Config& cfg);

class VoxelModel final : public ForwardModel {
 public:
  //! Voxelizes the deck's geometry; InputError for scenes the model cannot represent.
  explicit VoxelModel(const Config& cfg);
  ~VoxelModel() override;

  const Config& config() const override { return cfg_; }
  std::string kind() const override { return "voxel"; }
  Physics nominal() const override;
  double h() const override { return std::max({h_[0], h_[1], h_[2]}); }
  //! The cell edges along x, y, z (m).
  const Vec3d& spacing() const { return h_; }
  std::size_t nodes() const { return X_.size(); }
  std::size_t voxels() const override { return vox_node_.size(); }
  const std::vector<Vec3d>& rest_positions() const { return X_; }
  Vec3d voxel_center(std::size_t v) const override;
  double volume() const override {
    return h_[0] * h_[1] * h_[2] * static_cast<double>(vox_node_.size());
  }
  double exposed_area() const override;
  //! Voxel v's exposed area (m^2): its faces on empty space, clamp faces excluded.
  double voxel_exposed_area(std::size_t v) const { return vox_area_[v]; }
  //! The voxel whose cell holds X, or -1 where that cell is empty or outside the grid.
  long voxel_containing(const Vec3d& X) const;
  const std::array<long, 3>& voxel_ijk(std::size_t v) const override { return vox_ijk_[v]; }
  BoxRegion bounds() const override { return bounds_; }
  BoxRegion voxel_box(const std::vector<std::size_t>& voxels) const override;
  bool inside(const Vec3d& X) const override;
  //! InputError-free: call inside() first (throws std::logic_error if not).
  Attachment attach(const Vec3d& X) const override;
  std::vector<double> load_events() const override;
  Trace run(const Physics& phys, const std::vector<ChannelRequest>& req) const override;
  //! Inverse iteration on the linear stiffness and the mass from a uniform displacement
  //! along `direction`: what a change of voxels, stiffness or region does to the frequency,
  //! without a run (milliseconds on the 20x4x4 beam). NaN where a rest state does not capture
  //! the model this way (a spring clamp, contact planes) or the stiffness is singular (a body
  //! held nowhere).
  double rest_frequency(const Physics& phys, const Vec3d& direction) const override;
  //! The `count` lowest angular frequencies (rad/s) of the linear model at rest (stiffness at
  //! the physics' E, nu and stiffness effects; mass with the attached parts), by subspace
  //! iteration; empty where rest_frequency would be NaN.
  std::vector<double> rest_modes(const Physics& phys, int count) const;
  //! Whether StVK's elastic passes run in the vector kernel (the default) or in the scalar
  //! element loop; both give the same bits (tests and bench_diagnose compare them).
  void set_vector_kernels(bool on) { vector_kernels_ = on; }

 private:
  //! Each voxel's stiffness factor (at its centre).
  std::vector<double> stiffness_factors(const ModelTerms& terms) const;
  void add_point_masses();
  //! Adds an effect's rigid mass to the per-node masses pm (kg), as ModelTerms::AddedMass says;
  //! nothing where its tent holds no node.
  void spread_mass(const ModelTerms::AddedMass& am, std::vector<double>& pm) const;
  //! The linear stiffness and mass at rest on the free dofs; false where the model has no rest
  //! state of that kind (a spring clamp, contact planes).
  bool rest_matrices(const Physics& ph, Eigen::SparseMatrix<double>& K,
                     Eigen::SparseMatrix<double>& M, std::vector<int>& dof, int& ndof) const;
  //! Node n's mass (kg): its share of the body at `density` plus its attached parts'.
  double node_mass(std::size_t n, double density) const {
    return mass_[n] * density + point_mass_[n];
  }
  //! One run with the hyperelastic law as a compile-time type (Model.cpp).
  template <class Law>
  friend class VoxelRun;

  Config cfg_;
  bool vector_kernels_ = true;
  Vec3d h_{};  //!< cell edges along x, y, z
  Vec3d origin_{};
  std::array<long, 3> cells_{};
  std::vector<long> cell_voxel_;  //!< cell linear index -> voxel id or -1
  std::vector<std::array<int, 8>> vox_node_;
  std::vector<std::array<long, 3>> vox_ijk_;
  std::vector<Vec3d> X_;
  std::vector<double> mass_;        //!< per node, kg per unit density
  std::vector<double> point_mass_;  //!< per node, kg of the deck's [[point_mass]] parts
  std::vector<char> fixed_;         //!< per node
  std::vector<double> area_;        //!< exposed tributary area per node (not the clamp face)
  std::vector<double> vox_area_;    //!< exposed area per voxel (not the clamp face)
  //! Lumped spring area of a fixed node on no clamp face (an interior anchor), else 0.
  std::vector<double> clamp_area_;
  //! Clamp faces (exposed voxel faces whose corners are all fixed): their corners, indexed
  //! by the bits of the two face axes, so corners q and r share an edge when q ^ r has one bit.
  std::vector<std::array<int, 4>> clamp_faces_;
  std::vector<double> clamp_face_area_;   //!< area of each clamp face (m^2)
  std::vector<int> clamp_face_axis_;      //!< the axis normal to each clamp face
  std::vector<double> support_distance_;  //!< per node: distance to the nearest held node (m)
  BoxRegion bounds_;
};

}  // namespace gen4d::forward
