#include "elastogen/Elastodynamics.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <type_traits>

#include "core/Error.hpp"
#include "core/Log.hpp"
#include "materials/Arap.hpp"
#include "materials/FixedCorotated.hpp"
#include "materials/LinearElastic.hpp"
#include "materials/NeoHookean.hpp"
#include "materials/Registry.hpp"
#include "materials/StVK.hpp"
#include "neural/WeightSource.hpp"

namespace gen4d::elastogen {

namespace {
//! Adapts a pointwise material to the stencil's stress callback.
template <class Material>
auto stress_of(const Material& mat) {
  return [mat](const double* F, double* P) {
    materials::Mat3 Fm;
    for (int a = 0; a < 9; ++a) Fm.a[a] = F[a];
    materials::Mat3 Pm;
    const double psi = mat.energy_and_pk1(Fm, Pm);
    for (int a = 0; a < 9; ++a) P[a] = Pm.a[a];
    return psi;
  };
}

//! NeuralMTL evaluates the eight quadrature points of a voxel in one batch (the stencil
//! prefers the three-argument form), or one point at a time.
struct NeuralStress {
  neural::NeuralMaterial mat;
  double operator()(const double* F, double* P, int count) const {
    return mat.energy_and_pk1_cell(F, P, count);
  }
  double operator()(const double* F, double* P) const { return mat.energy_and_pk1_cell(F, P, 1); }
};
NeuralStress stress_of(const neural::NeuralMaterial& mat) {
  return NeuralStress{mat};
}

//! The stress callback of the voxel solver's internal forces (both solvers' residual): the
//! fixed corotated and ARAP laws take their rotation from a Newton polar iteration instead of
//! an SVD (same stress and energy to rounding); the others as stress_of.
template <class Material>
auto local_stress_of(const Material& mat) {
  if constexpr (std::is_same_v<Material, materials::FixedCorotated>)
    return CorotatedPolarStress{mat};
  else if constexpr (std::is_same_v<Material, materials::Arap>)
    return ArapPolarStress{mat};
  else
    return stress_of(mat);
}

//! Calls f with the true law of the deck (target "analytic" and the reference solver).
template <class F>
auto with_law(const MaterialConfig& m, F&& f) {
  const double E = m.youngs_modulus, nu = m.poisson_ratio;
  const auto at = m.param_where.find("model");  // an old spelling the deck wrote warns once
  const std::string law = materials::deck_law(m.model, materials::Solver::Voxel,
                                              at == m.param_where.end() ? "" : at->second);
  if (law == materials::NeoHookean::name)
    return f(materials::NeoHookean::from_young_poisson(E, nu));
  if (law == materials::StVK::name) return f(materials::StVK::from_young_poisson(E, nu));
  if (law == materials::LinearElastic::name)
    return f(materials::LinearElastic::from_young_poisson(E, nu));
  return f(materials::FixedCorotated::from_young_poisson(E, nu));
}

//! Calls f with the pointwise material the deck selects (ARAP for target "arap", NeuralMTL
//! with the true law's local weight k for "neural"); the runtime name picks one template
//! instantiation of the stencil loop.
template <class F>
auto with_material(const MaterialConfig& m, const neural::NeuralMtl* net, F&& f) {
  const double E = m.youngs_modulus, nu = m.poisson_ratio;
  if (m.target == "arap") return f(materials::Arap::from_young_poisson(E, nu));
  if (m.target == "neural") {
    const double k = with_law(m, [](const auto& law) { return law.projection_stiffness(); });
    return f(neural::NeuralMaterial{net, E, k});
  }
  return with_law(m, f);
}

std::unique_ptr<neural::NeuralMtl> network_for(const VoxelSystem& sys, const MaterialConfig& m) {
  if (m.target != "neural") return nullptr;
  return neural::load_network(sys.grid().comm(), m.neural_weights, m.model, m.poisson_ratio,
                              m.youngs_modulus);
}
//! The global step's stiffness k: the local model's projection stiffness, the largest over
//! the deck's materials (the step is a fixed-point iteration on the true residual, so k only
//! sets its rate; the stiffest material needs the largest).
double global_stiffness(const Config& cfg, const neural::NeuralMtl* net) {
  const auto k_of = [](const auto& m) { return m.projection_stiffness(); };
  double k = with_material(cfg.material, net, k_of);
  for (const MaterialConfig& r : cfg.material_regions)
    k = std::max(k, with_material(r, nullptr, k_of));
  return k;
}
}  // namespace

Elastodynamics::Elastodynamics(VoxelSystem& sys, const Config& cfg, PhaseTimers& timers)
    : sys_(sys),
      cfg_(cfg),
      timers_(timers),
      net_(network_for(sys, cfg.material)),
      dt_(cfg.dt),
      k_(global_stiffness(cfg, net_.get())),
      solver_(sys, cfg.solver, k_, cfg.dt, timers),
      anderson_(cfg.solver.anderson_depth, sys, solver_.reducer()) {
  if (cfg.solver.method == "newton") {
    // The reference solver always uses the true law, also when ElastoGen uses NeuralMTL.
    NewtonReference::Stress stress;
    const auto pointwise = [&](const auto& m) {
      stress = stress_of(m);
      return 0.0;
    };
    if (cfg.material.target == "neural")
      with_law(cfg.material, pointwise);
    else
      with_material(cfg.material, nullptr, pointwise);
    newton_ = std::make_unique<NewtonReference>(sys, std::move(stress), cfg.dt, timers);
  }
  const std::size_t n = 3 * sys_.ghosted().size();
  for (auto* a : {&x_, &v_, &xn_, &y_, &r_, &delta_, &fext_, &fint_}) a->assign(n, 0.0);
  // Applied forces are shared among a region's nodes by mass.
  std::vector<parallel::ExactSum> local(cfg_.forces.size());
  const auto& m = sys_.mass();
  for_owned(sys_.owned(), sys_.ghosted(), [&](std::size_t nn, long i, long j, long k) {
    if (!sys_.free_mask()[nn]) return;
    const auto p = sys_.rest_position(i, j, k);
    for (std::size_t f = 0; f < cfg_.forces.size(); ++f)
      if (cfg_.forces[f].region.contains({p[0], p[1], p[2]})) local[f].add(m[nn]);
  });
  force_region_mass_.assign(cfg_.forces.size(), 0.0);
  if (!local.empty()) solver_.reducer().sum(local.data(), force_region_mass_.data(), local.size());
  for (std::size_t f = 0; f < cfg_.forces.size(); ++f)
    if (force_region_mass_[f] == 0.0)
      log::info("warning: force region {} contains no free node of the object; it has no effect",
                f);
  for (const auto& c : cfg_.colliders) colliders_.emplace_back(c);
  build_traction_loads();
  reset_to_rest();
}

void Elastodynamics::build_traction_loads() {
  // Every boundary face (solid voxel on one side, empty voxel or outside on the other) sends a
  // quarter of its load to each of its 4 corner nodes. An owned node finds its share itself:
  // the faces through it separate pairs of its 8 neighbour voxels, which the ghosted
  // occupancy holds, so each share is computed by the rank that owns the node, in a fixed
  // order, whatever the decomposition (as the lumped masses are).
  const Vec3d& h = sys_.spacing();
  traction_loads_.assign(cfg_.tractions.size(), {});
  if (cfg_.tractions.empty()) return;
  std::vector<long long> local_quarters(cfg_.tractions.size(), 0);
  std::vector<parallel::ExactSum> local_area(cfg_.tractions.size());
  std::vector<std::array<double, 3>> load(cfg_.tractions.size());
  std::vector<int> faces(cfg_.tractions.size());
  for_owned(sys_.owned(), sys_.ghosted(), [&](std::size_t n, long i, long j, long k) {
    if (sys_.mass()[n] == 0.0) return;  // touches no solid voxel
    const auto p = sys_.rest_position(i, j, k);
    std::fill(load.begin(), load.end(), std::array<double, 3>{0.0, 0.0, 0.0});
    std::fill(faces.begin(), faces.end(), 0);
    for (int a = 0; a < 3; ++a) {
      const int b = (a + 1) % 3, c = (a + 2) % 3;
      const double quarter = 0.25 * h[b] * h[c];  // a quarter of the face's area
      for (int q = 0; q < 4; ++q) {
        // The face in the plane x_a = p_a between voxels `lower` and `upper` (bit a = 0 / 1).
        int lower = 0;
        lower |= (q & 1) << b;
        lower |= ((q >> 1) & 1) << c;
        const int upper = lower | 1 << a;
        auto solid = [&](int cell) {
          return sys_.solid(i - 1 + (cell & 1), j - 1 + ((cell >> 1) & 1),
                            k - 1 + ((cell >> 2) & 1));
        };
        const bool s_lo = solid(lower), s_hi = solid(upper);
        if (s_lo == s_hi) continue;
        double normal[3] = {0, 0, 0};  // outward: from the solid voxel to the empty one
        normal[a] = s_lo ? 1.0 : -1.0;
        Vec3d centre = {p[0], p[1], p[2]};
        centre[b] += ((lower >> b & 1) - 0.5) * h[b];
        centre[c] += ((lower >> c & 1) - 0.5) * h[c];
        for (std::size_t r = 0; r < cfg_.tractions.size(); ++r) {
          const TractionConfig& tc = cfg_.tractions[r];
          if (!tc.region.contains(centre)) continue;
          ++faces[r];
          local_area[r].add(quarter);
          for (int d = 0; d < 3; ++d)
            load[r][d] += quarter * (tc.traction[d] - tc.pressure * normal[d]);
        }
      }
    }
    for (std::size_t r = 0; r < cfg_.tractions.size(); ++r) {
      local_quarters[r] += faces[r];
      if (faces[r] > 0 && sys_.free_mask()[n])  // held nodes ignore loads, as with [[force]]
        traction_loads_[r].push_back({n, {load[r][0], load[r][1], load[r][2]}});
    }
  });
  std::vector<double> area(cfg_.tractions.size());
  solver_.reducer().sum(local_area.data(), area.data(), area.size());
  for (std::size_t r = 0; r < cfg_.tractions.size(); ++r) {
    const long long quarters = solver_.reducer().sum(local_quarters[r]);
    if (quarters == 0)
      log::info(
          "warning: traction region {} contains no boundary face of the object; it has no "
          "effect",
          r);
    else
      log::info("traction region {}: {} boundary faces, {:g} m^2", r, quarters / 4, area[r]);
  }
}

std::array<double, 3> Elastodynamics::traction_force(double t) {
  parallel::ExactSum s[3];
  for (std::size_t r = 0; r < cfg_.tractions.size(); ++r) {
    const TractionConfig& tc = cfg_.tractions[r];
    if (t < tc.start || t >= tc.end) continue;
    const double factor = tc.curve(t);
    for (const NodeLoad& l : traction_loads_[r])
      for (int d = 0; d < 3; ++d) s[d].add(factor * l.f[d]);
  }
  std::array<double, 3> g{};
  solver_.reducer().sum(s, g.data(), 3);
  return g;
}

std::array<double, 3> Elastodynamics::external_force(double t) {
  std::vector<double> f(fext_.size(), 0.0);
  external_forces(t, f);
  const auto& free = sys_.free_mask();
  parallel::ExactSum s[3];
  for_owned(sys_.owned(), sys_.ghosted(), [&](std::size_t n, long, long, long) {
    if (!free[n]) return;
    for (int d = 0; d < 3; ++d) s[d].add(f[3 * n + d]);
  });
  std::array<double, 3> g{};
  solver_.reducer().sum(s, g.data(), 3);
  return g;
}

void Elastodynamics::resolve_contacts(StepStats& st) {
  // After the implicit solve, as a post-step projection: each free owned node reads only its
  // own x^n and x, so the result does not depend on the decomposition. This is a first-order
  // (in dt) contact model: a resting body's support comes from nodes that sink into the
  // obstacle during each step's solve and are pushed back out, which lowers it by O(g dt^2)
  // times its mass over the contact nodes' mass (see inputs/README.md, [[collider]]).
  const auto& free = sys_.free_mask();
  long long contacts = 0;
  double deepest = 0;
  for_owned(sys_.owned(), sys_.ghosted(), [&](std::size_t n, long, long, long) {
    if (!free[n]) return;
    bool hit = false;
    for (const Collider& c : colliders_) {
      const double depth = c.resolve(&xn_[3 * n], &x_[3 * n]);
      if (depth > 0) {
        hit = true;
        deepest = std::max(deepest, depth);
      }
    }
    contacts += hit;
  });
  {
    PhaseTimers::Scope tt(timers_, "halo");
    solver_.halo().gather(x_.data());
  }
  PhaseTimers::Scope tt(timers_, "reduction");
  st.contacts = solver_.reducer().sum(contacts);
  st.penetration = solver_.reducer().max(deepest);
}

std::array<double, 3> Elastodynamics::prescribed(const KinematicConfig& k, const Vec3d& X,
                                                 double t) {
  // A [[curve]] scales the rates: the motion's progress is the curve's integral.
  const double tau = k.curve.empty()
                         ? std::min(std::max(t, k.start), k.end) - k.start
                         : k.curve.integral(k.start, std::min(std::max(t, k.start), k.end));
  const double w[3] = {k.angular_velocity[0], k.angular_velocity[1], k.angular_velocity[2]};
  const double wn = std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
  double r[3] = {X[0] - k.center[0], X[1] - k.center[1], X[2] - k.center[2]};
  if (wn > 0) {
    // Rodrigues: rotate r by angle |w| tau about w / |w|.
    const double a[3] = {w[0] / wn, w[1] / wn, w[2] / wn}, th = wn * tau;
    const double c = std::cos(th), s = std::sin(th), dot = a[0] * r[0] + a[1] * r[1] + a[2] * r[2];
    const double cr[3] = {a[1] * r[2] - a[2] * r[1], a[2] * r[0] - a[0] * r[2],
                          a[0] * r[1] - a[1] * r[0]};
    for (int d = 0; d < 3; ++d) r[d] = r[d] * c + cr[d] * s + a[d] * dot * (1 - c);
  }
  return {k.center[0] + r[0] + k.velocity[0] * tau, k.center[1] + r[1] + k.velocity[1] * tau,
          k.center[2] + r[2] + k.velocity[2] * tau};
}

void Elastodynamics::reset_to_rest() {
  const Box& G = sys_.ghosted();
  for (long k = G.start[2]; k < G.start[2] + G.count[2]; ++k)
    for (long j = G.start[1]; j < G.start[1] + G.count[1]; ++j)
      for (long i = G.start[0]; i < G.start[0] + G.count[0]; ++i) {
        const std::size_t n = G.index(i, j, k);
        const auto p = sys_.rest_position(i, j, k);
        for (int d = 0; d < 3; ++d) {
          x_[3 * n + d] = p[d];
          v_[3 * n + d] = 0.0;
        }
      }
}

void Elastodynamics::sync_ghosts() {
  PhaseTimers::Scope t(timers_, "halo");
  solver_.halo().gather(x_.data());
  solver_.halo().gather(v_.data());
}

void Elastodynamics::external_forces(double t, std::vector<double>& f) const {
  const auto& m = sys_.mass();
  for_owned(sys_.owned(), sys_.ghosted(), [&](std::size_t n, long i, long j, long k) {
    for (int d = 0; d < 3; ++d) f[3 * n + d] = m[n] * cfg_.gravity[d];
    if (!sys_.free_mask()[n]) return;
    const auto p = sys_.rest_position(i, j, k);
    for (std::size_t r = 0; r < cfg_.forces.size(); ++r) {
      const ForceConfig& fc = cfg_.forces[r];
      if (t < fc.start || t >= fc.end || force_region_mass_[r] == 0.0) continue;
      if (!fc.region.contains({p[0], p[1], p[2]})) continue;
      const double factor = fc.curve(t);
      for (int d = 0; d < 3; ++d)
        f[3 * n + d] += factor * fc.force[d] * m[n] / force_region_mass_[r];
    }
  });
  for (std::size_t r = 0; r < cfg_.tractions.size(); ++r) {
    const TractionConfig& tc = cfg_.tractions[r];
    if (t < tc.start || t >= tc.end) continue;
    const double factor = tc.curve(t);
    for (const NodeLoad& l : traction_loads_[r])
      for (int d = 0; d < 3; ++d) f[3 * l.node + d] += factor * l.f[d];
  }
}

bool Elastodynamics::has_preloads() const {
  return std::any_of(cfg_.forces.begin(), cfg_.forces.end(),
                     [](const ForceConfig& f) { return f.start < 0 && f.end >= 0; });
}

void Elastodynamics::preload_forces(std::vector<double>& f) const {
  const auto& m = sys_.mass();
  std::fill(f.begin(), f.end(), 0.0);
  for_owned(sys_.owned(), sys_.ghosted(), [&](std::size_t n, long i, long j, long k) {
    if (!sys_.free_mask()[n]) return;
    for (int d = 0; d < 3; ++d) f[3 * n + d] = m[n] * cfg_.gravity[d];
    const auto p = sys_.rest_position(i, j, k);
    for (std::size_t r = 0; r < cfg_.forces.size(); ++r) {
      const ForceConfig& fc = cfg_.forces[r];
      if (!(fc.start < 0 && fc.end >= 0) || force_region_mass_[r] == 0.0) continue;
      if (!fc.region.contains({p[0], p[1], p[2]})) continue;
      const double factor = fc.curve(0.0);
      for (int d = 0; d < 3; ++d)
        f[3 * n + d] += factor * fc.force[d] * m[n] / force_region_mass_[r];
    }
  });
}

void Elastodynamics::tangent_apply(std::vector<double>& v, std::vector<double>& y) {
  // K v = -(f_int(x + e v) - f_int(x)) / e (fint_ holds f_int(x)), e moving no node by more
  // than 1e-6 of a cell: the truncation error is ~1e-6 of K v at elastic strains (none for
  // a linear law), the rounding error ~1e-9; Newton's residual is exact whatever it is.
  const auto& free = sys_.free_mask();
  double vmax = 0;
  for_owned(sys_.owned(), sys_.ghosted(), [&](std::size_t n, long, long, long) {
    for (int d = 0; d < 3; ++d) {
      if (!free[n]) v[3 * n + d] = 0.0;
      vmax = std::max(vmax, std::fabs(v[3 * n + d]));
    }
  });
  vmax = solver_.reducer().max(vmax);
  std::fill(y.begin(), y.end(), 0.0);
  if (vmax == 0.0) return;
  solver_.halo().gather(v.data());
  const double e = 1e-6 * sys_.h() / vmax;
  std::vector<double>& xp = xn_;  // x_ + e v on the ghosted box
  std::vector<double>& fp = y_;
  for (std::size_t q = 0; q < x_.size(); ++q) xp[q] = x_[q] + e * v[q];
  internal_forces(xp, fp);
  for_owned(sys_.owned(), sys_.ghosted(), [&](std::size_t n, long, long, long) {
    if (!free[n]) return;
    for (int d = 0; d < 3; ++d) y[3 * n + d] = (fint_[3 * n + d] - fp[3 * n + d]) / e;
  });
}

PreloadStats Elastodynamics::settle_preloads() {
  PreloadStats st;
  reset_to_rest();
  long long held = 0;
  for_owned(sys_.owned(), sys_.ghosted(),
            [&](std::size_t n, long, long, long) { held += sys_.fixed_mask()[n]; });
  if (solver_.reducer().sum(held) == 0)
    throw InputError(cfg_.source +
                     ": [[force]] pre-loads (start < 0) need a [[fixed]] or [[kinematic]] "
                     "region to hold the body");
  const auto& free = sys_.free_mask();
  std::vector<double> f(fext_.size()), r(fext_.size()), p(fext_.size()), z(fext_.size()),
      kp(fext_.size()), dx(fext_.size()), diag;
  preload_forces(f);
  sys_.diagonal(k_, 0.0, diag);
  auto dot = [&](const std::vector<double>& a, const std::vector<double>& b) {
    parallel::ExactSum acc;
    for_owned(sys_.owned(), sys_.ghosted(), [&](std::size_t n, long, long, long) {
      if (!free[n]) return;
      for (int d = 0; d < 3; ++d) acc.add(a[3 * n + d] * b[3 * n + d]);
    });
    double g = 0;
    solver_.reducer().sum(&acc, &g, 1);
    return g;
  };
  // r = f_int(x) + f on free owned nodes: the negative gradient of phi(x) = E(x) - f.(x - X)
  // (X the rest positions, in x0 at the start); phi is returned in `phi`.
  std::vector<double> rest = x_;
  auto residual_at_x = [&](double& phi) {
    parallel::ExactSum acc[2];
    acc[0] = internal_forces(x_, fint_);
    for_owned(sys_.owned(), sys_.ghosted(), [&](std::size_t n, long, long, long) {
      for (int d = 0; d < 3; ++d) {
        const std::size_t q = 3 * n + d;
        r[q] = free[n] ? fint_[q] + f[q] : 0.0;
        acc[1].add(-f[q] * (x_[q] - rest[q]));
      }
    });
    double g[2];
    solver_.reducer().sum(acc, g, 2);
    phi = g[0] + g[1];
    return std::sqrt(dot(r, r));
  };
  const double fnorm = std::sqrt(dot(f, f));
  double phi = 0;
  double rnorm = residual_at_x(phi);
  constexpr int kMaxNewton = 20;
  constexpr long kMaxCg = 100000;
  const double tol = 1e-8 * fnorm;
  while (rnorm > tol && st.newton_iterations < kMaxNewton) {
    // K dx = r by Jacobi-preconditioned CG, to 1e-8 of ||r||.
    std::fill(dx.begin(), dx.end(), 0.0);
    for_owned(sys_.owned(), sys_.ghosted(), [&](std::size_t n, long, long, long) {
      for (int d = 0; d < 3; ++d) z[3 * n + d] = free[n] ? r[3 * n + d] / diag[n] : 0.0;
    });
    std::vector<double> res = r;
    p = z;
    double rz = dot(res, z);
    const double stop = 1e-8 * rnorm;
    for (long it = 0; it < kMaxCg; ++it) {
      tangent_apply(p, kp);
      const double pkp = dot(p, kp);
      if (!(pkp > 0)) break;
      const double alpha = rz / pkp;
      for_owned(sys_.owned(), sys_.ghosted(), [&](std::size_t n, long, long, long) {
        for (int d = 0; d < 3; ++d) {
          dx[3 * n + d] += alpha * p[3 * n + d];
          res[3 * n + d] -= alpha * kp[3 * n + d];
        }
      });
      ++st.cg_iterations;
      if (std::sqrt(dot(res, res)) <= stop) break;
      for_owned(sys_.owned(), sys_.ghosted(), [&](std::size_t n, long, long, long) {
        for (int d = 0; d < 3; ++d) z[3 * n + d] = free[n] ? res[3 * n + d] / diag[n] : 0.0;
      });
      const double rz_new = dot(res, z);
      const double beta = rz_new / rz;
      rz = rz_new;
      for_owned(sys_.owned(), sys_.ghosted(), [&](std::size_t n, long, long, long) {
        for (int d = 0; d < 3; ++d) p[3 * n + d] = z[3 * n + d] + beta * p[3 * n + d];
      });
    }
    // Backtracking: halve the step while it raises both the energy and the residual (stiff
    // stretching makes a full step's residual grow where the energy falls; near the solution
    // the energy's change is below its rounding and the residual decides).
    const std::vector<double> x0 = x_;
    double step = 1.0, trial = rnorm, phi_trial = phi;
    for (int half = 0; half < 12; ++half, step *= 0.5) {
      for_owned(sys_.owned(), sys_.ghosted(), [&](std::size_t n, long, long, long) {
        if (!free[n]) return;
        for (int d = 0; d < 3; ++d) x_[3 * n + d] = x0[3 * n + d] + step * dx[3 * n + d];
      });
      solver_.halo().gather(x_.data());
      trial = residual_at_x(phi_trial);
      if (phi_trial < phi || trial < rnorm) break;
    }
    ++st.newton_iterations;
    if (!(phi_trial < phi || trial < rnorm)) {  // no progress left at this precision
      x_ = x0;
      rnorm = residual_at_x(phi);
      break;
    }
    // A small residual that a Newton step hardly lowers is the rounding level of the forces.
    const bool stalled = trial > 0.5 * rnorm && trial < 1e-4 * fnorm;
    rnorm = trial;
    phi = phi_trial;
    if (stalled) break;
  }
  st.relative_residual = fnorm > 0 ? rnorm / fnorm : 0.0;
  std::fill(v_.begin(), v_.end(), 0.0);
  sync_ghosts();
  log::info(
      "pre-load: static equilibrium in {} Newton step(s), {} CG iterations, residual {:.2e} of "
      "the load",
      st.newton_iterations, st.cg_iterations, st.relative_residual);
  if (st.relative_residual > 1e-4)
    log::info("warning: the pre-load's static solve stopped at a residual of {:.2e} of the load",
              st.relative_residual);
  return st;
}

parallel::ExactSum Elastodynamics::internal_forces(const std::vector<double>& x,
                                                   std::vector<double>& f) {
  // The runtime choice of local model picks one instantiation of the stencil loop.
  return with_material(cfg_.material, net_.get(), [&](const auto& m) {
    if (cfg_.material_regions.empty())
      return sys_.internal_forces(local_stress_of(m), x.data(), f.data());
    // Several [[material]] entries share the law and target (the deck checks it): one stress
    // per slot, of the same type.
    using Law = std::decay_t<decltype(m)>;
    PerSlot<decltype(local_stress_of(m))> slots;
    slots.slots.push_back(local_stress_of(m));
    for (const MaterialConfig& r : cfg_.material_regions)
      with_material(r, nullptr, [&](const auto& mr) {
        if constexpr (std::is_same_v<std::decay_t<decltype(mr)>, Law>)
          slots.slots.push_back(local_stress_of(mr));
        else
          throw std::logic_error("[[material]] entries of different laws reached the voxel solver");
      });
    return sys_.internal_forces(slots, x.data(), f.data());
  });
}

double Elastodynamics::residual(const std::vector<double>& y, std::vector<double>& r) {
  parallel::ExactSum phi[2];  // elastic energy, inertia term
  {
    PhaseTimers::Scope t(timers_, "stencil+svd");
    phi[0].add(internal_forces(x_, fint_));
  }
  const auto& m = sys_.mass();
  const double inv_dt2 = 1.0 / (dt_ * dt_);
  reduce_owned(sys_.owned(), sys_.ghosted(), 1, &phi[1],
               [&](std::size_t n, long, long, long, parallel::ExactSum* acc) {
                 for (int d = 0; d < 3; ++d) {
                   const double dx = y[3 * n + d] - x_[3 * n + d];
                   r[3 * n + d] =
                       sys_.free_mask()[n] ? m[n] * dx * inv_dt2 + fint_[3 * n + d] : 0.0;
                   acc[0].add(0.5 * m[n] * dx * dx * inv_dt2);
                 }
               });
  double g[2];
  PhaseTimers::Scope t(timers_, "reduction");
  solver_.reducer().sum(phi, g, 2);
  return g[0] + g[1];
}

double Elastodynamics::owned_norm(const std::vector<double>& a, const std::vector<double>* b) {
  parallel::ExactSum s;
  reduce_owned(sys_.owned(), sys_.ghosted(), 1, &s,
               [&](std::size_t n, long, long, long, parallel::ExactSum* acc) {
                 if (!sys_.free_mask()[n]) return;
                 for (int d = 0; d < 3; ++d) {
                   const double v = b ? a[3 * n + d] - (*b)[3 * n + d] : a[3 * n + d];
                   acc[0].add(v * v);
                 }
               });
  double g = 0;
  PhaseTimers::Scope t(timers_, "reduction");
  solver_.reducer().sum(&s, &g, 1);
  return std::sqrt(g);
}

StepStats Elastodynamics::step(double t) {
  const auto& m = sys_.mass();
  const auto& free = sys_.free_mask();
  external_forces(t, fext_);
  xn_ = x_;
  parallel_owned(sys_.owned(), sys_.ghosted(), [&](std::size_t n, long, long, long) {
    for (int d = 0; d < 3; ++d) {
      const std::size_t q = 3 * n + d;
      y_[q] = free[n] ? xn_[q] + dt_ * v_[q] + dt_ * dt_ * fext_[q] / m[n] : xn_[q];
      // First iterate: the inertial prediction; Newton starts without the dt^2 f/m term,
      // which for large steps lands far outside its region of convergence.
      x_[q] = newton_ && free[n] ? xn_[q] + dt_ * v_[q] : y_[q];
    }
  });
  // Kinematic regions: their nodes take the prescribed pose at the end of the step.
  for_owned(sys_.owned(), sys_.ghosted(), [&](std::size_t n, long i, long j, long k) {
    if (!sys_.fixed_mask()[n]) return;
    const auto p = sys_.rest_position(i, j, k);
    for (const auto& kin : cfg_.kinematic) {
      if (!kin.region.contains({p[0], p[1], p[2]})) continue;
      const auto q = prescribed(kin, {p[0], p[1], p[2]}, t + dt_);
      for (int d = 0; d < 3; ++d) x_[3 * n + d] = y_[3 * n + d] = q[d];
    }
  });
  {
    PhaseTimers::Scope tt(timers_, "halo");
    solver_.halo().gather(x_.data());
  }
  StepStats st;
  const auto& scfg = cfg_.solver;
  anderson_.reset();
  double phi = 0;  // implicit-Euler objective at x_
  auto gather_x = [&] {
    PhaseTimers::Scope tt(timers_, "halo");
    solver_.halo().gather(x_.data());
  };
  auto outer_loop = [&]() {
    const InnerStats in = solver_.solve(r_, delta_);
    st.sweeps += in.sweeps;
    x_prev_ = x_;
    const bool mixed = anderson_.mix(x_prev_, delta_, x_);
    gather_x();
    double phi_new = residual(y_, r_);
    if (mixed && phi_new > phi) {
      // The accelerated iterate raised the objective: take the plain local-global step.
      ++st.rejected;
      anderson_.reset();
      parallel_owned(sys_.owned(), sys_.ghosted(), [&](std::size_t n, long, long, long) {
        for (int d = 0; d < 3; ++d) x_[3 * n + d] = x_prev_[3 * n + d] + delta_[3 * n + d];
      });
      gather_x();
      phi_new = residual(y_, r_);
    }
    phi = phi_new;
    ++st.outer;
    const double dn = owned_norm(x_, &x_prev_), sn = owned_norm(x_, &xn_);
    st.relative_change = dn > 0.0 ? dn / sn : 0.0;
  };
  if (newton_) {
    // Reference path: Newton's method on the true objective, same discretisation.
    const NewtonStats ns = newton_->solve(
        x_,
        [&](const std::vector<double>& x, std::vector<double>& r) {
          x_ = x;
          residual(y_, r);
        },
        solver_.halo());
    st.outer = ns.newton_iterations;
    st.sweeps = ns.krylov_iterations;
    residual(y_, r_);
  } else {
    // RNN-1: local targets from the latest x, then the global relaxation, until x settles.
    phi = residual(y_, r_);
    while (st.outer < scfg.max_outer) {
      outer_loop();
      if (st.relative_change < scfg.outer_tolerance) break;
    }
  }
  // Accuracy check on the true implicit-Euler residual (seed App. G), bounded extra loops.
  const double fext_norm = owned_norm(fext_);
  auto accuracy = [&]() {
    parallel::ExactSum s;
    reduce_owned(sys_.owned(), sys_.ghosted(), 1, &s,
                 [&](std::size_t n, long, long, long, parallel::ExactSum* acc) {
                   if (!free[n]) return;
                   for (int d = 0; d < 3; ++d) {
                     const double a = m[n] * (x_[3 * n + d] - y_[3 * n + d]) / (dt_ * dt_);
                     acc[0].add(a * a);
                   }
                 });
    double inertia2 = 0;
    solver_.reducer().sum(&s, &inertia2, 1);
    const double denom = std::sqrt(inertia2) + fext_norm;
    const double rn = owned_norm(r_);
    return denom > 0.0 ? rn / denom : rn;
  };
  st.accuracy = accuracy();
  while (!newton_ && st.accuracy > scfg.accuracy_tolerance && st.extra < scfg.max_extra_outer) {
    outer_loop();
    ++st.extra;
    st.accuracy = accuracy();
  }
  st.accurate = st.accuracy <= scfg.accuracy_tolerance;
  // Static colliders act on the end-of-step positions, identically for both solvers.
  if (!colliders_.empty()) resolve_contacts(st);
  parallel_owned(sys_.owned(), sys_.ghosted(), [&](std::size_t n, long, long, long) {
    for (int d = 0; d < 3; ++d) v_[3 * n + d] = (x_[3 * n + d] - xn_[3 * n + d]) / dt_;
  });
  {
    PhaseTimers::Scope tt(timers_, "halo");
    solver_.halo().gather(v_.data());
  }
  return st;
}

Elastodynamics::Energy Elastodynamics::energy() {
  Energy e;
  parallel::ExactSum s[3];
  s[1] = internal_forces(x_, fint_);
  const auto& m = sys_.mass();
  for_owned(sys_.owned(), sys_.ghosted(), [&](std::size_t n, long, long, long) {
    for (int d = 0; d < 3; ++d) {
      s[0].add(0.5 * m[n] * v_[3 * n + d] * v_[3 * n + d]);
      s[2].add(-m[n] * cfg_.gravity[d] * x_[3 * n + d]);
    }
  });
  double g[3];
  solver_.reducer().sum(s, g, 3);
  e.kinetic = g[0];
  e.elastic = g[1];
  e.gravity = g[2];
  return e;
}

}  // namespace gen4d::elastogen
