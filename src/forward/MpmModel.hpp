//! The MPM solver (PhysGaussian's MLS-MPM, src/mpm) as a forward model of `gen4d diagnose`:
//! one serial run per Physics on MPI_COMM_SELF, at a fixed substep, with the deck's particles,
//! grid and [[boundary]] conditions. Markers are attached by their reference point: a marker
//! moves with the B-spline-weighted mean displacement of the particles seeded around it (the
//! grid's own interpolation kernel, 1.5 cells wide), so it follows the body as its Gaussians do.
//! The deck's [[point_mass]] entries are added to the particles in their regions
//! (mpm/PointMass.hpp), as in the MPM solver; a region without particles is an InputError at
//! construction.
//
// Effects it represents: the deck's E, nu and density; gravity; Rayleigh damping (mass: on the
// grid velocity; stiffness: a viscous Kirchhoff stress beta (2 mu D + lambda tr(D) I) of the
// particle's rate of deformation D, the symmetric part of its APIC velocity gradient); a
// one-term Prony series (a fraction g of the stress relaxes with time tau, in the frame that
// rotates with the particle); a box region whose particles' stress is scaled by a factor (for
// the elastic laws, E times the factor at the same nu); air drag and dry friction on the
// particles (a particle carries its voxel's share of the exposed area); von Mises plasticity
// with linear hardening and the swap among the elastic laws (fixed corotated, Neo-Hookean,
// StVK-Hencky) when the deck's material is one of those; a ground plane with Coulomb friction,
// applied before the deck's own colliders. Clamp compliance is left out: an MPM deck has no
// [[fixed]] supports, its [[boundary]] conditions are kinematic.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "forward/Model.hpp"

namespace gen4d::geometry {
class Shape;
}

namespace gen4d::forward {

class MpmModel final : public ForwardModel {
 public:
  //! InputError for a deck that is not an MPM deck, or whose material cannot be built.
  explicit MpmModel(const Config& cfg);
  ~MpmModel() override;

  const Config& config() const override { return cfg_; }
  std::string kind() const override { return "mpm"; }
  //! The deck's values; law is "corotated", "neo_hookean" or "stvk" for the elastic MPM models
  //! (fixed_corotated, neo_hookean, stvk_hencky), else the MPM model's name; dt is the fixed
  //! substep of every run (see substep()).
  Physics nominal() const override;
  double h() const override { return cells_->h(); }
  std::size_t voxels() const override { return cells_->voxels(); }
  Vec3d voxel_center(std::size_t v) const override { return cells_->voxel_center(v); }
  const std::array<long, 3>& voxel_ijk(std::size_t v) const override {
    return cells_->voxel_ijk(v);
  }
  BoxRegion voxel_box(const std::vector<std::size_t>& v) const override {
    return cells_->voxel_box(v);
  }
  BoxRegion bounds() const override { return cells_->bounds(); }
  double volume() const override { return cells_->volume(); }
  double exposed_area() const override { return cells_->exposed_area(); }
  bool inside(const Vec3d& X) const override { return cells_->inside(X); }
  Attachment attach(const Vec3d& X) const override;
  //! Start and end times of the deck's [[boundary]] conditions.
  std::vector<double> load_events() const override;
  Trace run(const Physics& phys, const std::vector<ChannelRequest>& req) const override;
  double rest_frequency(const Physics&, const Vec3d&) const override {
    return std::numeric_limits<double>::quiet_NaN();
  }
  bool models(const std::string& effect, const std::string& variant) const override;
  std::string unsupported_reason(const std::string& effect) const override;
  bool samples_accelerations() const override { return false; }
  //! The fixed substep: simulation.dt with mpm.substep = "fixed"; else the smaller of
  //! simulation.dt and half the elastic limit wave_cfl dx / c at the deck's material (so a fit
  //! may raise E four-fold before the instability guard stops a run). Runs do not adapt their
  //! substep: an adaptive one would make the prediction jump with the parameters.
  double substep() const { return dt_; }
  //! Whether the deck's material is one of the elastic laws (plasticity and the law swap apply).
  bool elastic_deck() const { return elastic_; }

 private:
  Config cfg_;
  std::unique_ptr<VoxelModel> cells_;  //!< the deck's cells at the grid size (geometry queries)
  std::shared_ptr<const geometry::Shape> shape_;
  double dt_ = 0;
  bool elastic_ = false;
};

}  // namespace gen4d::forward
