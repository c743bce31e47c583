#include "diagnose/MpmModel.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "core/Error.hpp"
#include "geometry/Shape.hpp"
#include "mpm/MpmSimulation.hpp"
#include "mpm/Seeding.hpp"
#include "mpm/Solver.hpp"

namespace gen4d::diagnose {

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
  elastic_ = law_of_mpm_model(cfg.material.model) != nullptr;
  cells_ = std::make_unique<VoxelModel>(cells_config(cfg));
  shape_ = geometry::make_shape(cfg.geometry);
  const double limit = cfg.mpm.wave_cfl * cfg.voxel_size / std::max(material->wave_speed(), 1e-300);
  dt_ = cfg.mpm.substep == "fixed" ? cfg.dt : std::min(cfg.dt, 0.5 * limit);
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
  if (effect == "gravity" || effect == "contact_friction") return true;
  if (effect == "damping") return variant.empty() || variant == "mass";
  if (effect == "plasticity") return elastic_;
  if (effect == "material_law") return elastic_ && (variant.empty() || mpm_model_of_law(variant));
  return false;
}

std::string MpmModel::unsupported_reason(const std::string& effect) const {
  if (effect == "plasticity" || effect == "material_law")
    return fmt::format("the deck's MPM material '{}' is not one of the elastic laws",
                       cfg_.material.model);
  if (effect == "damping") return "the MPM model damps by mass (alpha) only";
  return "a term of the voxel model only";
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
    // The material of this physics.
    mpm::MaterialParams mp;
    mp.source = cfg_.source;
    if (elastic_) {
      const char* m = mpm_model_of_law(ph.law);
      if (!m) throw InputError("law '" + ph.law + "' has no MPM model");
      mp.model = m;
      if (std::isfinite(ph.yield_stress)) {
        mp.model = "von_mises";  // Hencky elasticity with J2 return mapping
        mp.values["yield_stress"] = ph.yield_stress;
        mp.values["hardening"] = ph.hardening;
      }
    } else {
      mp.model = cfg_.material.model;
      mp.values = cfg_.material.params;
    }
    mp.values["youngs_modulus"] = ph.youngs_modulus;
    mp.values["poisson_ratio"] = ph.poisson_ratio;
    mp.values["density"] = ph.density;
    std::shared_ptr<const mpm::Material> material = mpm::make_material(mp);

    mpm::SolverOptions opt;
    opt.gravity = ph.gravity;
    opt.max_dt = ph.dt;
    opt.adaptive = false;
    opt.cfl = cfg_.mpm.cfl;
    opt.wave_cfl = cfg_.mpm.wave_cfl;
    opt.remove_outside = cfg_.mpm.out_of_domain == "remove";
    opt.boundary_layers = cfg_.mpm.boundary_layers;
    opt.max_cells_per_substep = cfg_.mpm.max_cells_per_substep;
    opt.damping = ph.rayleigh_alpha;
    // The effect's ground first: where it lies on a plane of the deck, its friction acts on
    // the approaching velocity before the deck's plane sees it.
    std::vector<BoundaryConfig> bcs;
    // Its plane acts on the grid nodes: blended over a cell above it, so that the run changes
    // continuously with the height (a fit's finite differences see it move).
    if (ph.ground) {
      bcs.push_back(mpm::surface_collider("separate", {0, 0, ph.ground_height}, {0, 0, 1},
                                          ph.ground_friction));
      bcs.back().soft_width = cfg_.voxel_size;
    }
    bcs.insert(bcs.end(), cfg_.boundaries.begin(), cfg_.boundaries.end());

    const mpm::GridSpec spec = mpm::layout_grid(cfg_, shape_->bounds());
    mpm::Solver solver(MPI_COMM_SELF, spec, material, opt, bcs);
    solver.distribute(mpm::seed_particles(MPI_COMM_SELF, spec, *shape_, cfg_.mpm.particles_per_axis,
                                          *material, cfg_.mpm.velocity));
    const mpm::Particles& P = solver.particles();
    const std::size_t np = P.size();
    if (np == 0) throw InputError(cfg_.source + ": the geometry holds no MPM particle");
    // Each marker: the particles within the kernel of its reference point, and their weights.
    struct Member {
      std::int64_t id;
      double w;
      std::array<double, 3> x0;
    };
    std::vector<std::vector<Member>> members(req.size());
    const double inv_dx = 1.0 / spec.dx;
    for (std::size_t c = 0; c < req.size(); ++c) {
      const Vec3d& X = req[c].at.X;
      double wsum = 0;
      for (std::size_t i = 0; i < np; ++i) {
        const double w = bspline((P.x[3 * i] - X[0]) * inv_dx) *
                         bspline((P.x[3 * i + 1] - X[1]) * inv_dx) *
                         bspline((P.x[3 * i + 2] - X[2]) * inv_dx);
        if (w <= 0) continue;
        members[c].push_back({P.id[i], w, {P.x[3 * i], P.x[3 * i + 1], P.x[3 * i + 2]}});
        wsum += w;
      }
      if (members[c].empty())
        throw InputError(fmt::format(
            "no MPM particle within 1.5 cells of the marker at ({}, {}, {})", X[0], X[1], X[2]));
      for (auto& m : members[c]) m.w /= wsum;
    }
    std::unordered_map<std::int64_t, std::size_t> index;
    auto reindex = [&] {
      index.clear();
      for (std::size_t i = 0; i < P.size(); ++i) index[P.id[i]] = i;
    };
    reindex();
    // Marker positions now; a marker whose particles all left (removed) keeps NaN.
    auto positions = [&](std::vector<double>& out) {
      out.assign(3 * req.size(), std::nan(""));
      for (std::size_t c = 0; c < req.size(); ++c) {
        double u[3] = {0, 0, 0}, wsum = 0;
        for (const auto& m : members[c]) {
          auto it = index.find(m.id);
          if (it == index.end()) continue;
          const double* x = &P.x[3 * it->second];
          for (int a = 0; a < 3; ++a) u[a] += m.w * (x[a] - m.x0[a]);
          wsum += m.w;
        }
        if (wsum > 0)
          for (int a = 0; a < 3; ++a) out[3 * c + a] = req[c].at.X[a] + u[a] / wsum;
      }
    };
    std::vector<std::size_t> next(req.size(), 0);  // next sample of each channel
    std::vector<double> prev, cur;
    double t = 0;
    auto sample = [&](double t0, double t1, bool last) {
      for (std::size_t c = 0; c < req.size(); ++c)
        while (next[c] < req[c].t.size() && (req[c].t[next[c]] <= t1 || last)) {
          const double ts = req[c].t[next[c]];
          const double f = t1 > t0 ? std::clamp((ts - t0) / (t1 - t0), 0.0, 1.0) : 1.0;
          for (int a = 0; a < 3; ++a)
            tr.channel[c][3 * next[c] + a] = (1 - f) * prev[3 * c + a] + f * cur[3 * c + a];
          ++next[c];
        }
    };
    std::vector<double> tau(9 * np);
    auto stresses = [&] {
      const std::size_t n = P.size();
      tau.resize(9 * n);
      material->stress(n, P.F.data(), P.state.data(), tau.data());
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
    };
    positions(cur);
    prev = cur;
    sample(0, 0, false);  // samples at t = 0
    const long steps = static_cast<long>(std::ceil(t_end / ph.dt - 1e-9));
    for (long k = 0; k < steps; ++k) {
      const double dt = std::min(ph.dt, t_end - t);
      if (!(dt > 0)) break;
      const double t1 = (k + 1 == steps) ? t_end : t + dt;
      // Markers are located only around substeps a sample falls in (at 200 Hz, one in ~20).
      bool any = false;
      for (std::size_t c = 0; c < req.size(); ++c)
        any = any || (next[c] < req[c].t.size() && req[c].t[next[c]] <= t1);
      if (any) positions(prev);  // at t, before the substep
      solver.substep(t, dt);
      ++tr.steps;
      if (P.size() != index.size()) reindex();
      if (any) {
        positions(cur);
        sample(t, t1, false);
        stresses();
      }
      t = t1;
    }
    positions(cur);
    prev = cur;
    sample(t, t, true);
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

}  // namespace gen4d::diagnose
