#include "forward/MpmModel.hpp"

#include <fmt/format.h>

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "core/Error.hpp"
#include "geometry/Shape.hpp"
#include "materials/Svd3.hpp"
#include "mpm/MpmSimulation.hpp"
#include "mpm/PointMass.hpp"
#include "mpm/Seeding.hpp"
#include "mpm/Solver.hpp"

namespace gen4d::forward {

namespace {

//! Diagnose's law names for the elastic MPM models, and back.
const char* law_of_mpm_model(const std::string& m) {
  if (m == "fixed_corotated") return "corotated";
  if (m == "neo_hookean") return "neo_hookean";
  if (m == "stvk_hencky") return "stvk";
  return nullptr;
}
const char* mpm_model_of_law(const std::string& law) {
  if (law == "corotated") return "fixed_corotated";
  if (law == "neo_hookean") return "neo_hookean";
  if (law == "stvk") return "stvk_hencky";
  return nullptr;
}

//! Quadratic B-spline, the MPM grid's kernel (support |r| < 1.5).
double bspline(double r) {
  r = std::abs(r);
  if (r < 0.5) return 0.75 - r * r;
  if (r < 1.5) return 0.5 * (1.5 - r) * (1.5 - r);
  return 0;
}

//! The geometry-only copy of an MPM deck the voxel cells are built from.
Config cells_config(const Config& cfg) {
  Config c = cfg;
  c.solver.method = "newton";
  c.material.model = "corotated";
  c.boundaries.clear();
  c.fixed.clear();
  c.kinematic.clear();
  c.forces.clear();
  c.colliders.clear();
  c.tractions.clear();
  return c;
}

//! Each particle's share of the body's exposed area (m^2, indexed by particle id): the
//! exposed faces of the voxel (of `cells`, the deck's voxels at the grid size) holding its
//! reference position, split evenly among that voxel's particles. Particles outside every
//! voxel carry none.
std::vector<double> particle_areas(const VoxelModel& cells, const mpm::Particles& P) {
  std::int64_t nid = 0;
  for (std::size_t i = 0; i < P.size(); ++i) nid = std::max(nid, P.id[i] + 1);
  std::vector<long> home(static_cast<std::size_t>(nid), -1);
  std::vector<int> count(cells.voxels(), 0);
  for (std::size_t i = 0; i < P.size(); ++i) {
    const long v = cells.voxel_containing({P.x[3 * i], P.x[3 * i + 1], P.x[3 * i + 2]});
    if (v < 0) continue;
    home[static_cast<std::size_t>(P.id[i])] = v;
    ++count[static_cast<std::size_t>(v)];
  }
  std::vector<double> out(static_cast<std::size_t>(nid), 0.0);
  for (std::size_t id = 0; id < out.size(); ++id)
    if (home[id] >= 0) {
      const auto v = static_cast<std::size_t>(home[id]);
      out[id] = cells.voxel_exposed_area(v) / count[v];
    }
  return out;
}

//! The rotation of F's polar decomposition F = R U (row-major F, as the particles store it):
//! Higham's Newton iteration, the signed SVD's rotation where that declines, as the voxel
//! model's corotated stress takes it.
Eigen::Matrix3d rotation_of(const double* F) {
  materials::Mat3 M;
  std::copy(F, F + 9, M.a);
  materials::Mat3 R;
  if (!materials::polar_rotation_newton(M, R)) R = materials::polar_rotation(M);
  return Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(R.a);
}

//! The MPM material of a physics: the deck's elastic law (von Mises over Hencky elasticity
//! where plasticity applies), or the deck's own material, at the physics' E, nu and density.
std::shared_ptr<const mpm::Material> run_material(const Config& cfg, bool elastic,
                                                  const Physics& ph, const ModelTerms& tm) {
  mpm::MaterialParams mp;
  mp.source = cfg.source;
  if (elastic) {
    const char* m = mpm_model_of_law(ph.law);
    if (!m) throw InputError("law '" + ph.law + "' has no MPM model");
    mp.model = m;
    if (std::isfinite(tm.yield_stress)) {
      mp.model = "von_mises";  // Hencky elasticity with J2 return mapping
      mp.values["yield_stress"] = tm.yield_stress;
      mp.values["hardening"] = tm.hardening;
    }
  } else {
    mp.model = cfg.material.model;
    mp.values = cfg.material.params;
  }
  mp.values["youngs_modulus"] = ph.youngs_modulus;
  mp.values["poisson_ratio"] = ph.poisson_ratio;
  mp.values["density"] = ph.density;
  return mpm::make_material(mp);
}

//! The effects that act on the particles' stresses (see the header): the region's stress
//! factor, the Prony term's relaxing stress and the stiffness damping's viscous stress, as the
//! solver's stress hook. Its per-id arrays are filled once the particles are seeded.
class StressEffects {
 public:
  StressEffects(const Physics& ph, const ModelTerms& tm)
      : tm_(tm),
        region_(std::any_of(tm.stiffness_boxes.begin(), tm.stiffness_boxes.end(),
                            [](const ModelTerms::StiffnessBox& b) { return b.factor != 1.0; })),
        visco_(tm.prony_g > 0),
        kv_(tm.rayleigh_beta != 0),
        mu0_(ph.youngs_modulus / (2 * (1 + ph.poisson_ratio))),
        lambda0_(ph.youngs_modulus * ph.poisson_ratio /
                 ((1 + ph.poisson_ratio) * (1 - 2 * ph.poisson_ratio))) {}

  //! Sets the hook in opt where any of the effects applies (this must outlive the solver).
  void install(mpm::SolverOptions& opt) {
    if (region_ || visco_ || kv_)
      opt.stress_hook = [this](const mpm::Particles& Q, double* tau, double dt) {
        apply(Q, tau, dt);
      };
  }

  //! The per-id arrays of the seeded particles P (ids below nid).
  void seeded(const mpm::Particles& P, std::int64_t nid) {
    if (region_) {
      factor_.assign(static_cast<std::size_t>(nid), 1.0);
      for (std::size_t i = 0; i < P.size(); ++i)
        factor_[static_cast<std::size_t>(P.id[i])] =
            tm_.stiffness_factor({P.x[3 * i], P.x[3 * i + 1], P.x[3 * i + 2]});
    }
    if (visco_) history_.assign(9 * static_cast<std::size_t>(nid), 0.0);
  }

 private:
  void apply(const mpm::Particles& Q, double* tau, double dt) {
    const double rv = visco_ ? dt / tm_.prony_tau : 0.0;
    for (std::size_t i = 0; i < Q.size(); ++i) {
      const auto id = static_cast<std::size_t>(Q.id[i]);
      double* s = tau + 9 * i;
      const double f = region_ ? factor_[id] : 1.0;
      if (f != 1.0)
        for (int k = 0; k < 9; ++k) s[k] *= f;
      if (visco_) {
        // q' = (g P - q) / tau, backward Euler, in the rotated frame R^T tau R so that a
        // rigid rotation carries the relaxing stress along.
        const Eigen::Matrix3d R = rotation_of(&Q.F[9 * i]);
        Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> S(s);
        Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> q(&history_[9 * id]);
        q = (q + rv * tm_.prony_g * (R.transpose() * S * R)) / (1.0 + rv);
        S -= R * q * R.transpose();
      }
      if (kv_) {
        const double* C = &Q.C[9 * i];
        const double tr = C[0] + C[4] + C[8];
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b)
            s[3 * a + b] += tm_.rayleigh_beta * f *
                            (mu0_ * (C[3 * a + b] + C[3 * b + a]) + (a == b ? lambda0_ * tr : 0.0));
      }
    }
  }

  const ModelTerms& tm_;
  const bool region_, visco_, kv_;
  const double mu0_, lambda0_;
  std::vector<double> factor_;   //!< stress factor by id (region)
  std::vector<double> history_;  //!< Prony stress by id, 9 each, in the particle's rotated frame
};

//! The markers of a run's requests: each the particles within the kernel of its reference
//! point, with their weights; their positions, and the samples between two of them.
class Markers {
 public:
  Markers(const std::vector<ChannelRequest>& req, const mpm::Particles& P, double dx)
      : req_(req), P_(P), members_(req.size()), next_(req.size(), 0) {
    const double inv_dx = 1.0 / dx;
    for (std::size_t c = 0; c < req.size(); ++c) {
      const Vec3d& X = req[c].at.X;
      double wsum = 0;
      for (std::size_t i = 0; i < P.size(); ++i) {
        const double w = bspline((P.x[3 * i] - X[0]) * inv_dx) *
                         bspline((P.x[3 * i + 1] - X[1]) * inv_dx) *
                         bspline((P.x[3 * i + 2] - X[2]) * inv_dx);
        if (w <= 0) continue;
        members_[c].push_back({P.id[i], w, {P.x[3 * i], P.x[3 * i + 1], P.x[3 * i + 2]}});
        wsum += w;
      }
      if (members_[c].empty())
        throw InputError(fmt::format(
            "no MPM particle within 1.5 cells of the marker at ({}, {}, {})", X[0], X[1], X[2]));
      for (auto& m : members_[c]) m.w /= wsum;
    }
    reindex();
  }

  //! After particles were removed: where each id now sits.
  void reindex() {
    index_.clear();
    for (std::size_t i = 0; i < P_.size(); ++i) index_[P_.id[i]] = i;
  }
  bool stale() const { return P_.size() != index_.size(); }

  //! Whether a sample falls at or before t1.
  bool due(double t1) const {
    bool any = false;
    for (std::size_t c = 0; c < req_.size(); ++c)
      any = any || (next_[c] < req_[c].t.size() && req_[c].t[next_[c]] <= t1);
    return any;
  }

  //! Marker positions now; a marker whose particles all left (removed) keeps NaN.
  void positions(std::vector<double>& out) const {
    out.assign(3 * req_.size(), std::nan(""));
    for (std::size_t c = 0; c < req_.size(); ++c) {
      double u[3] = {0, 0, 0}, wsum = 0;
      for (const auto& m : members_[c]) {
        auto it = index_.find(m.id);
        if (it == index_.end()) continue;
        const double* x = &P_.x[3 * it->second];
        for (int a = 0; a < 3; ++a) u[a] += m.w * (x[a] - m.x0[a]);
        wsum += m.w;
      }
      if (wsum > 0)
        for (int a = 0; a < 3; ++a) out[3 * c + a] = req_[c].at.X[a] + u[a] / wsum;
    }
  }

  //! The samples in (t0, t1] (all that are left, when last), linear between the positions
  //! prev at t0 and cur at t1, into tr.
  void sample(double t0, double t1, bool last, const std::vector<double>& prev,
              const std::vector<double>& cur, Trace& tr) {
    for (std::size_t c = 0; c < req_.size(); ++c)
      while (next_[c] < req_[c].t.size() && (req_[c].t[next_[c]] <= t1 || last)) {
        const double ts = req_[c].t[next_[c]];
        const double f = t1 > t0 ? std::clamp((ts - t0) / (t1 - t0), 0.0, 1.0) : 1.0;
        for (int a = 0; a < 3; ++a)
          tr.channel[c][3 * next_[c] + a] = (1 - f) * prev[3 * c + a] + f * cur[3 * c + a];
        ++next_[c];
      }
  }

 private:
  struct Member {
    std::int64_t id;
    double w;
    std::array<double, 3> x0;
  };
  const std::vector<ChannelRequest>& req_;
  const mpm::Particles& P_;
  std::vector<std::vector<Member>> members_;
  std::unordered_map<std::int64_t, std::size_t> index_;
  std::vector<std::size_t> next_;  //!< next sample of each channel
};

//! The largest von Mises stress and particle speed of the particles P into tr (tau: scratch).
void track_peaks(const mpm::Material& material, const mpm::Particles& P, std::vector<double>& tau,
                 Trace& tr) {
  const std::size_t n = P.size();
  tau.resize(9 * n);
  material.stress(n, P.F.data(), P.state.data(), tau.data());
  for (std::size_t i = 0; i < n; ++i) {
    const double* s = &tau[9 * i];
    const double m = (s[0] + s[4] + s[8]) / 3;
    const double d0 = s[0] - m, d1 = s[4] - m, d2 = s[8] - m;
    const double j2 = 0.5 * (d0 * d0 + d1 * d1 + d2 * d2) +
                      0.25 * ((s[1] + s[3]) * (s[1] + s[3]) + (s[2] + s[6]) * (s[2] + s[6]) +
                              (s[5] + s[7]) * (s[5] + s[7]));
    tr.max_mises = std::max(tr.max_mises, std::sqrt(3 * j2));
    const double* v = &P.v[3 * i];
    tr.max_speed = std::max(tr.max_speed, std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]));
  }
}

//! The effects' node forces (air drag, dry friction) on the free particles' velocities, in
//! library order (NodeForce::apply_to_particle); area: exposed area by particle id.
void apply_node_forces(const ModelTerms& tm, const std::vector<double>& area, double dt,
                       mpm::Particles& P) {
  for (std::size_t i = 0; i < P.size(); ++i) {
    if (P.flag[i] != 0) continue;  // frozen or kinematic
    double* v = &P.v[3 * i];
    double speed = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    const ForceNode node{P.mass[i], area[static_cast<std::size_t>(P.id[i])]};
    for (const auto& nf : tm.node_forces) nf->apply_to_particle(node, dt, v, speed);
  }
}

}  // namespace

MpmModel::MpmModel(const Config& cfg) : cfg_(cfg) {
  if (cfg.solver.method != "mpm")
    throw InputError(cfg.source + ": MpmModel needs solver.method = \"mpm\"");
  if (!(cfg.dt > 0) || !(cfg.end_time > 0))
    throw InputError(cfg.source + ": keys 'simulation.dt' and 'simulation.end_time' must be > 0");
  for (const auto& what : {std::make_pair(!cfg.fixed.empty(), "[[fixed]]"),
                           std::make_pair(!cfg.kinematic.empty(), "[[kinematic]]"),
                           std::make_pair(!cfg.forces.empty(), "[[force]]"),
                           std::make_pair(!cfg.colliders.empty(), "[[collider]]"),
                           std::make_pair(!cfg.tractions.empty(), "[[traction]]")})
    if (what.first)
      throw InputError(
          fmt::format("{}: {} does not apply to solver.method = \"mpm\" (the MPM solver takes "
                      "[[boundary]] conditions: cuboid, surface_collider, particle_impulse, ...)",
                      cfg.source, what.second));
  const auto material = mpm::make_deck_material(cfg);  // InputError naming the key
  if (!cfg.material_regions.empty())
    throw InputError(cfg.material_regions[0].where +
                     ": several [[material]] entries are not supported by gen4d diagnose (it "
                     "fits one material)");
  elastic_ = law_of_mpm_model(cfg.material.model) != nullptr;
  cells_ = std::make_unique<VoxelModel>(cells_config(cfg));
  shape_ = geometry::make_shape(cfg.geometry);
  const double limit = cfg.mpm.wave_cfl * cfg.voxel_size / std::max(material->wave_speed(), 1e-300);
  dt_ = cfg.mpm.substep == "fixed" ? cfg.dt : std::min(cfg.dt, 0.5 * limit);
  // A [[point_mass]] region without particles is the deck's error, not a failed run.
  if (!cfg.point_masses.empty()) {
    mpm::Particles p =
        mpm::seed_particles(MPI_COMM_SELF, mpm::layout_grid(cfg_, shape_->bounds()), *shape_,
                            cfg.mpm.particles_per_axis, *material, cfg.mpm.velocity);
    mpm::add_point_masses(MPI_COMM_SELF, cfg.point_masses, p);
  }
}

MpmModel::~MpmModel() = default;

Physics MpmModel::nominal() const {
  Physics p;
  const char* law = law_of_mpm_model(cfg_.material.model);
  p.law = law ? law : cfg_.material.model;
  p.youngs_modulus = cfg_.material.youngs_modulus;
  p.poisson_ratio = cfg_.material.poisson_ratio;
  p.density = cfg_.material.density;
  p.gravity = cfg_.gravity;
  p.dt = dt_;
  return p;
}

Attachment MpmModel::attach(const Vec3d& X) const {
  Attachment at;
  at.X = X;
  return at;
}

std::vector<double> MpmModel::load_events() const {
  std::vector<double> e;
  for (const auto& b : cfg_.boundaries) {
    if (b.start > 0 && b.start < cfg_.end_time) e.push_back(b.start);
    if (b.end < cfg_.end_time) e.push_back(b.end);
  }
  std::sort(e.begin(), e.end());
  e.erase(std::unique(e.begin(), e.end()), e.end());
  return e;
}

bool MpmModel::models(const std::string& effect, const std::string& variant) const {
  if (effect == "plasticity") return elastic_;
  if (effect == "material_law") return elastic_ && (variant.empty() || mpm_model_of_law(variant));
  // The supports' effects need [[fixed]] nodes; added masses are terms of the voxel model.
  for (const char* voxel_only :
       {"clamp_compliance", "support_rotation", "support_friction", "added_mass", "sensor_mass"})
    if (effect == voxel_only) return false;
  return true;
}

std::string MpmModel::unsupported_reason(const std::string& effect) const {
  if (effect == "plasticity" || effect == "material_law")
    return fmt::format("the deck's MPM material '{}' is not one of the elastic laws",
                       cfg_.material.model);
  if (effect == "clamp_compliance" || effect == "support_rotation" || effect == "support_friction")
    return "an MPM deck has no [[fixed]] supports (its [[boundary]] conditions are kinematic)";
  if (effect == "added_mass" || effect == "sensor_mass")
    return "added rigid masses are terms of the voxel model";
  return "not a term of the MPM model";
}

Trace MpmModel::run(const Physics& ph, const std::vector<ChannelRequest>& req) const {
  Trace tr;
  tr.channel.resize(req.size());
  double t_end = 0;
  for (const auto& r : req) {
    if (r.acceleration) throw std::logic_error("MpmModel samples positions only");
    if (!r.t.empty()) t_end = std::max(t_end, r.t.back());
    tr.channel[&r - req.data()].assign(3 * r.t.size(), std::nan(""));
  }
  try {
    const ModelTerms tm = model_terms(ph);
    const std::shared_ptr<const mpm::Material> material = run_material(cfg_, elastic_, ph, tm);
    mpm::SolverOptions opt = mpm::solver_options(cfg_);
    opt.gravity = ph.gravity;  // the physics under test, fixed substeps
    opt.max_dt = ph.dt;
    opt.adaptive = false;
    opt.damping = tm.rayleigh_alpha;
    StressEffects stress_effects(ph, tm);
    stress_effects.install(opt);
    // The effects' planes first: where one lies on a plane of the deck, its friction acts on
    // the approaching velocity before the deck's plane sees it. They act on the grid nodes:
    // blended over a cell above them, so that the run changes continuously with the height (a
    // fit's finite differences see it move).
    std::vector<BoundaryConfig> bcs;
    for (const auto& c : tm.planes) {
      bcs.push_back(mpm::surface_collider("separate", c.point, c.normal, c.friction));
      bcs.back().soft_width = cfg_.voxel_size;
    }
    bcs.insert(bcs.end(), cfg_.boundaries.begin(), cfg_.boundaries.end());

    const mpm::GridSpec spec = mpm::layout_grid(cfg_, shape_->bounds());
    mpm::Solver solver(MPI_COMM_SELF, spec, material, opt, bcs);
    mpm::Particles seeded = mpm::seed_particles(
        MPI_COMM_SELF, spec, *shape_, cfg_.mpm.particles_per_axis, *material, cfg_.mpm.velocity);
    mpm::add_point_masses(MPI_COMM_SELF, cfg_.point_masses, seeded);
    solver.distribute(std::move(seeded));
    mpm::Particles& P = solver.particles();
    const std::size_t np = P.size();
    if (np == 0) throw InputError(cfg_.source + ": the geometry holds no MPM particle");
    std::int64_t nid = 0;
    for (std::size_t i = 0; i < np; ++i) nid = std::max(nid, P.id[i] + 1);
    stress_effects.seeded(P, nid);
    std::vector<double> area;
    if (!tm.node_forces.empty()) area = particle_areas(*cells_, P);
    Markers markers(req, P, spec.dx);
    std::vector<double> prev, cur, tau(9 * np);
    double t = 0;
    markers.positions(cur);
    prev = cur;
    markers.sample(0, 0, false, prev, cur, tr);  // samples at t = 0
    const long steps = static_cast<long>(std::ceil(t_end / ph.dt - 1e-9));
    for (long k = 0; k < steps; ++k) {
      const double dt = std::min(ph.dt, t_end - t);
      if (!(dt > 0)) break;
      const double t1 = (k + 1 == steps) ? t_end : t + dt;
      // Markers are located only around substeps a sample falls in (at 200 Hz, one in ~20).
      const bool any = markers.due(t1);
      if (any) markers.positions(prev);  // at t, before the substep
      if (!tm.node_forces.empty()) apply_node_forces(tm, area, dt, P);
      solver.substep(t, dt);
      ++tr.steps;
      if (markers.stale()) markers.reindex();
      if (any) {
        markers.positions(cur);
        markers.sample(t, t1, false, prev, cur, tr);
        track_peaks(*material, P, tau, tr);
      }
      t = t1;
    }
    markers.positions(cur);
    prev = cur;
    markers.sample(t, t, true, prev, cur, tr);
    for (const auto& ch : tr.channel)
      for (double x : ch)
        if (!std::isfinite(x)) {
          tr.ok = false;
          tr.failure = "a marker's particles left the grid (removed)";
          return tr;
        }
  } catch (const mpm::InstabilityError& e) {
    tr.ok = false;
    tr.failure = e.what();
  } catch (const InputError& e) {
    tr.ok = false;
    tr.failure = e.what();
  }
  return tr;
}

}  // namespace gen4d::forward
