//! What the applied effects add to one forward run, gathered once per run by the forward models
//! (VoxelModel, MpmModel) from the effects' hooks (Effect::add_terms). The constitutive and
//! support terms live inside the models' loops, so an effect hands them plain coefficients;
//! a force on the nodes (or particles) is a NodeForce the models call per node.
#pragma once

#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "core/Config.hpp"

namespace gen4d::forward {

//! A node of the voxel model or a particle of the MPM model, as a NodeForce sees it.
struct ForceNode {
  double mass = 0;  //!< kg
  double area = 0;  //!< exposed area it carries, m^2 (clamp faces excluded)
  //! Its reference position, m; support_distance: how far it lies from the nearest [[fixed]]
  //! node, m (the voxel model; infinite where the deck holds nothing, and in the MPM model).
  Vec3d X{0, 0, 0};
  double support_distance = std::numeric_limits<double>::infinity();
};

//! A force on every free node (voxel model) or particle (MPM model). Its damping part is
//! linear in the velocity and enters the voxel model's step matrix; the rest is explicit.
class NodeForce {
 public:
  virtual ~NodeForce() = default;
  //! Linear damping per node dof, N s/m: the force -c v (voxel model; default none).
  virtual double damping(const ForceNode&) const { return 0; }
  //! Adds the rest of the force's negative to the residual r (3) of a free node of the voxel
  //! model, whose velocity is v1 at the step's end and v0 at its start (dt the step).
  virtual void add_residual(const ForceNode&, const double v1[3], const double v0[3], double dt,
                            double r[3]) const = 0;
  //! Applies the whole force to a free particle's velocity v over a substep dt before its
  //! particle-to-grid transfer (MPM model). `speed` is |v| on entry, kept equal to it (a
  //! following force reads it).
  virtual void apply_to_particle(const ForceNode&, double dt, double v[3], double& speed) const = 0;
};

//! A plane the body cannot cross (point, unit normal), with Coulomb friction.
struct ContactPlane {
  Vec3d point{0, 0, 0}, normal{0, 0, 1};
  double friction = 0;
};

struct ModelTerms;

//! What a forward model asks of an effect (diagnose's effects are TermSources): a name, for
//! the memo keys and logs, and the terms it adds to a run at given term values.
class TermSource {
 public:
  virtual ~TermSource() = default;
  virtual std::string name() const = 0;
  //! The forward models' hook: adds the terms with values `terms` to t (once per run).
  virtual void add_terms(const std::vector<double>& /*terms*/, ModelTerms& /*t*/) const {}
};

//! The terms of one run, at their null values where no applied effect sets them.
struct ModelTerms {
  //! Rayleigh damping: alpha M v, and beta times the elastic law's stress of the strain rate.
  double rayleigh_alpha = 0, rayleigh_beta = 0;
  //! One Prony term: a fraction prony_g of the stress relaxes with time prony_tau.
  double prony_g = 0, prony_tau = 1;
  //! Von Mises plasticity with linear isotropic hardening (Hencky elasticity); none at inf.
  double yield_stress = std::numeric_limits<double>::infinity(), hardening = 0;
  //! The [[fixed]] nodes on springs and dashpots per unit clamp area (Pa/m, Pa s/m); rigid at
  //! inf.
  double clamp_stiffness = std::numeric_limits<double>::infinity(), clamp_damping = 0;
  //! Stiffness factor boxes: material whose reference point lies in `box` has E * factor.
  struct StiffnessBox {
    BoxRegion box;
    double factor = 1;
  };
  std::vector<StiffnessBox> stiffness_boxes;
  //! Contact planes besides the deck's colliders.
  std::vector<ContactPlane> planes;
  //! Rigid masses added to the body (voxel model): `mass` kg over the nodes whose reference
  //! position lies within `spread` (m, per axis) of `at`, weighted by a tent
  //! prod_a max(0, 1 - |X_a - at_a| / spread_a) times the node's own mass, so the mass and its
  //! centre move continuously with `at` (spread = the cell edges: a sensor's trilinear weights).
  struct AddedMass {
    Vec3d at{0, 0, 0}, spread{1, 1, 1};
    double mass = 0;
  };
  std::vector<AddedMass> added_masses;
  //! The [[fixed]] nodes held rigidly along their clamp face's plane but on springs of this
  //! stiffness per unit clamp area along its normal (Pa/m; rigid at inf): a support that gives in
  //! rotation (a vise's jaws) but not in translation.
  double clamp_normal_stiffness = std::numeric_limits<double>::infinity();
  //! Forces on the nodes, in library order.
  std::vector<std::shared_ptr<const NodeForce>> node_forces;

  //! The stiffness factor at reference point X: the last box's holding it, else 1.
  double stiffness_factor(const Vec3d& X) const {
    double f = 1;
    for (const auto& b : stiffness_boxes)
      if (b.box.contains(X)) f = b.factor;
    return f;
  }
};

}  // namespace gen4d::forward
