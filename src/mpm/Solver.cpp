#include "mpm/Solver.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/Device.hpp"
#include "core/ParallelFor.hpp"
#include "mpm/HostKernels.hpp"
#include "mpm/Kernels.hpp"
#include "parallel/Comm.hpp"
#include "parallel/Reduce.hpp"

namespace gen4d::mpm {

using kernels::dot3;

namespace {

// Contributions are at most 2^kQuantumBits quanta, so 2^(53 - kQuantumBits) of them can meet
// at one node before a sum could lose exactness.
constexpr int kQuantumBits = 40;

//! Inverse quantum (a power of two) for contributions bounded by `bound`.
double inverse_quantum(double bound) {
  if (!(bound > 0) || !std::isfinite(bound)) return 1.0;
  return std::ldexp(1.0, kQuantumBits - std::ilogb(bound) - 1);
}

inline bool active(const BoundaryConfig& b, double t) {
  return t >= b.start && t < b.end;
}

}  // namespace

SolverOptions solver_options(const Config& cfg) {
  SolverOptions opt;
  opt.gravity = cfg.gravity;
  opt.max_dt = cfg.dt;
  opt.adaptive = cfg.mpm.substep == "adaptive";
  opt.cfl = cfg.mpm.cfl;
  opt.wave_cfl = cfg.mpm.wave_cfl;
  opt.remove_outside = cfg.mpm.out_of_domain == "remove";
  opt.boundary_layers = cfg.mpm.boundary_layers;
  opt.max_cells_per_substep = cfg.mpm.max_cells_per_substep;
  opt.rpic_damping = cfg.mpm.rpic_damping;
  opt.grid_velocity_scale = cfg.mpm.grid_velocity_scale;
  return opt;
}

Solver::Solver(MPI_Comm comm, const GridSpec& grid, MaterialSet materials,
               const SolverOptions& options, std::vector<BoundaryConfig> boundaries)
    : comm_(comm),
      spec_(grid),
      materials_(std::move(materials)),
      opt_(options),
      bcs_(std::move(boundaries)) {
  rank_ = parallel::rank(comm_);
  size_ = parallel::size(comm_);
  for (int a = 0; a < 3; ++a)
    if (spec_.cells[a] < 2 * opt_.boundary_layers + 3)
      throw InputError(
          fmt::format("mpm grid: {} cells along axis {} is too few; it needs at least {} (2 x "
                      "mpm.boundary_layers + 3)",
                      spec_.cells[a], "xyz"[a], 2 * opt_.boundary_layers + 3));
}

Solver::~Solver() = default;

bool Solver::on_device() const {
#if defined(GEN4D_CUDA)
  return device_ != nullptr;
#else
  return false;
#endif
}

int Solver::owner_of(const double* x) const {
  int owner = 0;
  for (int a = 0; a < 3; ++a) {
    const double X = (x[a] - spec_.lo[a]) / spec_.dx;
    const long last = static_cast<long>(rank_part_[a].size()) - 2;
    owner += rank_part_[a][std::clamp(static_cast<long>(std::floor(X + 0.5)), 1L, last)];
  }
  return owner;
}

void Solver::distribute(Particles local) {
  p_ = std::move(local);
  const auto nodes = spec_.nodes();
  // Per-axis histograms of nearest nodes over all ranks, split into equal-count slabs.
  const auto procs = parallel::NodeGrid::process_grid(comm_, nodes);
  std::array<std::vector<long>, 3> ownership;
  for (int a = 0; a < 3; ++a) {
    std::vector<long long> hist(static_cast<std::size_t>(nodes[a]), 0);
    for (std::size_t i = 0; i < p_.size(); ++i) {
      const double X = (p_.x[3 * i + a] - spec_.lo[a]) / spec_.dx;
      const long n = std::clamp(static_cast<long>(std::floor(X + 0.5)), 0L, nodes[a] - 1);
      ++hist[static_cast<std::size_t>(n)];
    }
    parallel::sum_in_place(comm_, hist.data(), static_cast<int>(hist.size()));
    long long total = 0;
    for (auto h : hist) total += h;
    const int m = procs[a];
    constexpr long kMinSlab = 3;  // nodes per slab (a ghost layer needs at least one)
    std::vector<long> cuts{0};
    long long cum = 0;
    long node = 0;
    for (int s = 1; s < m; ++s) {
      const long long target = total * s / m;
      while (node < nodes[a] && cum + hist[static_cast<std::size_t>(node)] <= target)
        cum += hist[static_cast<std::size_t>(node++)];
      long cut = std::max(node, cuts.back() + kMinSlab);
      cut = std::min(cut, nodes[a] - kMinSlab * (m - s));
      cuts.push_back(cut);
      while (node < cut) cum += hist[static_cast<std::size_t>(node++)];
    }
    cuts.push_back(nodes[a]);
    for (int s = 0; s < m; ++s) ownership[a].push_back(cuts[s + 1] - cuts[s]);
  }
  grid_ = std::make_unique<parallel::NodeGrid>(comm_, nodes, ownership);
  // The owner of node (i, j, k) is the sum of one term per axis (ranks are numbered x fastest).
  for (int a = 0; a < 3; ++a) {
    rank_part_[a].resize(static_cast<std::size_t>(nodes[a]));
    for (long n = 0; n < nodes[a]; ++n)
      rank_part_[a][static_cast<std::size_t>(n)] =
          grid_->owner_of(a == 0 ? n : 0, a == 1 ? n : 0, a == 2 ? n : 0);
  }
  halo4_ = std::make_unique<parallel::Halo>(*grid_, 4);
  const std::size_t ng = static_cast<std::size_t>(grid_->ghosted_nodes().size());
  pm_.assign(4 * ng, 0.0);
#if defined(GEN4D_CUDA)
  if (opt_.allow_device && exec::use_device() && !device_) device_ = device::make_workspace();
#endif
  vel_.assign(3 * ng + 1, 0.0);  // one spare: G2P loads a node's velocity as four doubles

  // Ranges of the sequential-release conditions over the initial particles.
  release_range_.assign(bcs_.size(), {0.0, 0.0});
  for (std::size_t b = 0; b < bcs_.size(); ++b) {
    if (bcs_[b].type != "release_particles_sequentially") continue;
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (std::size_t i = 0; i < p_.size(); ++i) {
      const double s = dot3(&p_.x[3 * i], bcs_[b].normal.data());
      lo = std::min(lo, s);
      hi = std::max(hi, s);
    }
    lo = parallel::min_of(comm_, lo);
    hi = parallel::max_of(comm_, hi);
    release_range_[b] = {lo, hi};
  }
  for (std::size_t i = 0; i < p_.size(); ++i)
    if (frozen(i, 0.0)) p_.flag[i] |= 1;
  migrate();
}

bool Solver::frozen(std::size_t i, double t) const {
  for (std::size_t b = 0; b < bcs_.size(); ++b) {
    const BoundaryConfig& bc = bcs_[b];
    if (bc.type != "release_particles_sequentially") continue;
    if (t >= bc.end) continue;
    const auto [lo, hi] = release_range_[b];
    const double s = dot3(&p_.x[3 * i], bc.normal.data());
    const double frac = hi > lo ? (s - lo) / (hi - lo) : 0.0;
    const int layer = std::min(bc.layers - 1, static_cast<int>(frac * bc.layers));
    const double release = bc.start + (bc.end - bc.start) * layer / bc.layers;
    if (t < release) return true;
  }
  return false;
}

double Solver::stable_dt(double limit) const {
  double dt = std::min(limit, opt_.max_dt);
  if (!opt_.adaptive) return dt;
  // The fastest particle and the fastest elastic wave of the particles' current state.
  const double* vel = p_.v.data();
  double most[2] = {
      exec::parallel_reduce_max(static_cast<long>(p_.size()), 0.0,
                                [&](long i) { return dot3(&vel[3 * i], &vel[3 * i]); }),
      materials_.state_wave_speed(p_.size(), p_.material.data(), p_.state.data())};
  parallel::max_in_place(comm_, most, 2);
  const double vmax = std::sqrt(most[0]), c = most[1];
  if (vmax > 0) dt = std::min(dt, opt_.cfl * spec_.dx / vmax);
  if (c > 0) dt = std::min(dt, opt_.wave_cfl * spec_.dx / c);
  return dt;
}

void Solver::substep(double t, double dt) {
  {
    PhaseTimers::Scope s(timers_, "material");
    update_stress(dt);
  }
  {
    PhaseTimers::Scope s(timers_, "p2g");
    p2g(dt);
  }
  {
    PhaseTimers::Scope s(timers_, "halo");
    halo4_->scatter_add(pm_.data());
  }
  {
    PhaseTimers::Scope s(timers_, "grid");
    grid_update(t, dt);
  }
  {
    PhaseTimers::Scope s(timers_, "g2p");
    g2p(t, dt);
  }
  {
    PhaseTimers::Scope s(timers_, "guard");
    check_and_confine(t, dt);
  }
  {
    PhaseTimers::Scope s(timers_, "migration");
    migrate();
  }
}

void Solver::update_stress(double dt) {
  tau_.resize(9 * p_.size());
  if (p_.size() > 0)
    materials_.update(p_.size(), p_.material.data(), p_.F.data(), p_.state.data(), tau_.data(), dt);
  if (opt_.stress_hook && p_.size() > 0) opt_.stress_hook(p_, tau_.data(), dt);
}

void Solver::p2g(double dt) {
  const long n = static_cast<long>(p_.size());
  const parallel::Box& gb = grid_->ghosted_nodes();
  kernels::P2GArgs a{};
  a.x = p_.x.data();
  a.v = p_.v.data();
  a.C = p_.C.data();
  a.tau = tau_.data();
  a.mass = p_.mass.data();
  a.vol0 = p_.vol0.data();
  a.flag = p_.flag.data();
  for (int d = 0; d < 3; ++d) {
    a.lo[d] = spec_.lo[d];
    a.start[d] = gb.start[d];
  }
  a.dx = spec_.dx;
  const double inv_dx = 1.0 / spec_.dx;
  a.stress_scale = -dt * 4.0 * inv_dx * inv_dx;
  a.rpic = opt_.rpic_damping;
  a.gx = gb.count[0];
  a.gy = gb.count[1];
  // Quanta from the global largest contributions.
  double bound[2] = {0, 0};
  {
    const long T = n < exec::kSerialBelow ? 1 : exec::host_threads();
    std::vector<double> block(2 * static_cast<std::size_t>(T), 0.0);
    exec::parallel_for_dynamic(T, [&](long k) {
      host::p2g_bound(a, n * k / T, n * (k + 1) / T, &block[2 * static_cast<std::size_t>(k)]);
    });
    for (std::size_t k = 0; k < block.size(); k += 2)
      for (int c = 0; c < 2; ++c) bound[c] = kernels::max_of(bound[c], block[k + c]);
  }
  parallel::max_in_place(comm_, bound, 2);
  a.inv_qm = inverse_quantum(bound[0]);
  a.inv_qp = inverse_quantum(bound[1]);
  quantum_mass_ = 1.0 / a.inv_qm;
  quantum_mom_ = 1.0 / a.inv_qp;

  double* grid = pm_.data();
  exec::parallel_for(static_cast<long>(pm_.size()), [&](long k) { grid[k] = 0.0; });
#if defined(GEN4D_CUDA)
  if (device_) {
    device::p2g(*device_, a, n, grid, static_cast<long>(gb.size()));
    return;
  }
#endif
  if (exec::host_threads() == 1 || n < exec::kSerialBelow) {
    host::p2g(a, nullptr, 0, n, grid);
    return;
  }
  // Threads scatter slabs of base cells along z, two cells thick: slabs 2 apart touch disjoint
  // nodes, so the even slabs run side by side, then the odd ones, with plain additions.
  constexpr long kSlab = 2;
  const long slabs = (gb.count[2] + kSlab - 1) / kSlab;
  slab_start_.assign(static_cast<std::size_t>(slabs) + 1, 0);
  slab_of_.resize(static_cast<std::size_t>(n));
  for (long i = 0; i < n; ++i) {
    const double X = (a.x[3 * i + 2] - a.lo[2]) / a.dx;
    const long base = static_cast<long>(std::floor(X - 0.5)) - a.start[2];
    const long s = std::clamp(base / kSlab, 0L, slabs - 1);
    slab_of_[static_cast<std::size_t>(i)] = static_cast<std::int32_t>(s);
    ++slab_start_[static_cast<std::size_t>(s) + 1];
  }
  for (long s = 0; s < slabs; ++s) slab_start_[s + 1] += slab_start_[s];
  order_.resize(static_cast<std::size_t>(n));
  {
    std::vector<long> fill(slab_start_.begin(), slab_start_.end() - 1);
    for (long i = 0; i < n; ++i) order_[static_cast<std::size_t>(fill[slab_of_[i]]++)] = i;
  }
  for (long parity = 0; parity < 2; ++parity)
    exec::parallel_for_dynamic((slabs - parity + 1) / 2, [&](long k) {
      const long s = parity + 2 * k;
      host::p2g(a, order_.data(), slab_start_[s], slab_start_[s + 1], grid);
    });
}

void Solver::grid_update(double t, double dt) {
  const parallel::Box& gb = grid_->ghosted_nodes();
  const auto nodes = spec_.nodes();
  bool walls = true;
  bool has_box_entry = false;
  for (const auto& b : bcs_)
    if (b.type == "bounding_box") {
      has_box_entry = true;
      walls = active(b, t);
    }
  if (!has_box_entry) walls = true;
  // The conditions acting at t, in deck order, as kernel records.
  grid_conditions_.clear();
  for (const auto& bc : bcs_) {
    kernels::GridCondition c{};
    const bool resetting = bc.type == "cuboid" && t >= bc.end && t < bc.end + bc.reset_duration;
    if (resetting) {
      c.kind = kernels::GridCondition::kReset;
      grid_conditions_.push_back(c);
      continue;
    }
    if (!active(bc, t)) continue;
    if (bc.type == "cuboid") {
      c.kind = kernels::GridCondition::kCuboid;
      const BoxRegion box = cuboid_region(bc, t);
      const double factor = bc.curve(t);
      for (int d = 0; d < 3; ++d) {
        c.lo[d] = box.lo[d];
        c.hi[d] = box.hi[d];
        c.velocity[d] = bc.velocity[d] * factor;
      }
    } else if (bc.type == "surface_collider") {
      c.kind = bc.surface == "sticky"     ? kernels::GridCondition::kSticky
               : bc.surface == "cut"      ? kernels::GridCondition::kCut
               : bc.surface == "separate" ? kernels::GridCondition::kSeparate
                                          : kernels::GridCondition::kSlip;
      for (int d = 0; d < 3; ++d) {
        c.lo[d] = bc.region.lo[d];
        c.hi[d] = bc.region.hi[d];
        c.point[d] = bc.point[d];
        c.normal[d] = bc.normal[d];
      }
      c.friction = bc.friction;
      c.soft_width = bc.soft_width;
      c.cut_scale = bc.cut_scale;
    } else {
      continue;  // particle conditions act in G2P
    }
    grid_conditions_.push_back(c);
  }
  kernels::GridArgs a{};
  a.pm = pm_.data();
  a.vel = vel_.data();
  a.qm = quantum_mass_;
  a.qp = quantum_mom_;
  for (int d = 0; d < 3; ++d) {
    a.gravity[d] = opt_.gravity[d];
    a.lo[d] = spec_.lo[d];
    a.start[d] = gb.start[d];
    a.count[d] = gb.count[d];
    a.nodes[d] = nodes[d];
  }
  a.dt = dt;
  a.damp = opt_.damping > 0 ? 1.0 / (1.0 + opt_.damping * dt) : 1.0;
  a.scale_v = opt_.grid_velocity_scale;
  a.dx = spec_.dx;
  a.wall_layers = walls ? opt_.boundary_layers : -1;
  a.cond = grid_conditions_.data();
  a.ncond = static_cast<int>(grid_conditions_.size());
#if defined(GEN4D_CUDA)
  if (device_) {
    device::grid_update(*device_, a, static_cast<long>(gb.size()));
    return;
  }
#endif
  exec::parallel_for(static_cast<long>(gb.size()), [&](long k) { kernels::grid_node(a, k); });
}

void Solver::g2p(double t, double dt) {
  const long n = static_cast<long>(p_.size());
  const parallel::Box& gb = grid_->ghosted_nodes();
  bool any_release = false, particle_bcs = false;
  for (const auto& b : bcs_) {
    any_release |= b.type == "release_particles_sequentially";
    particle_bcs |=
        active(b, t) && (b.type == "particle_impulse" || b.type == "enforce_particle_translation" ||
                         b.type == "enforce_particle_velocity_rotation");
  }
  if (any_release)
    exec::parallel_for(n, [&](long i) {
      if (frozen(static_cast<std::size_t>(i), t + dt))
        p_.flag[i] |= 1;
      else
        p_.flag[i] &= static_cast<std::uint8_t>(~1u);
    });
  kernels::G2PArgs a{};
  a.x = p_.x.data();
  a.v = p_.v.data();
  a.C = p_.C.data();
  a.F = p_.F.data();
  a.flag = p_.flag.data();
  a.vel = vel_.data();
  for (int d = 0; d < 3; ++d) {
    a.lo[d] = spec_.lo[d];
    a.start[d] = gb.start[d];
  }
  a.dx = spec_.dx;
  a.dt = dt;
  a.gx = gb.count[0];
  a.gy = gb.count[1];
  a.advance = !particle_bcs;
#if defined(GEN4D_CUDA)
  if (device_)
    device::g2p(*device_, a, n, static_cast<long>(gb.size()));
  else
#endif
  {
    // The guard rides along while each particle is in cache (check_and_confine acts on it).
    const kernels::GuardArgs guard = guard_args(dt);
    status_.resize(static_cast<std::size_t>(n));
    exec::parallel_blocks(n, [&](long b, long e) { host::g2p(a, b, e, &guard, status_.data()); });
    guarded_ = a.advance;
  }
  if (a.advance) return;
  particle_conditions(t, dt);
  exec::parallel_for(n, [&](long i) {
    if (p_.flag[i] & 1) return;
    for (int d = 0; d < 3; ++d) a.x[3 * i + d] += dt * a.v[3 * i + d];
    kernels::advance_deformation(&a.C[9 * i], dt, &a.F[9 * i]);
  });
}

void Solver::particle_conditions(double t, double dt) {
  const std::size_t n = p_.size();
  for (const auto& bc : bcs_) {
    // Collective decisions only depend on t, identical on every rank.
    if (!active(bc, t)) continue;
    const double factor = bc.curve(t);
    if (bc.type == "particle_impulse") {
      parallel::ExactSum local;
      for (std::size_t i = 0; i < n; ++i)
        if (!(p_.flag[i] & 1) &&
            bc.region.contains({p_.x[3 * i], p_.x[3 * i + 1], p_.x[3 * i + 2]}))
          local.add(p_.mass[i]);
      double region_mass = 0;
      parallel::Reducer(comm_).sum(&local, &region_mass, 1);
      if (!(region_mass > 0)) continue;
      for (std::size_t i = 0; i < n; ++i)
        if (!(p_.flag[i] & 1) &&
            bc.region.contains({p_.x[3 * i], p_.x[3 * i + 1], p_.x[3 * i + 2]}))
          for (int d = 0; d < 3; ++d) p_.v[3 * i + d] += dt * (bc.force[d] * factor) / region_mass;
    } else if (bc.type == "enforce_particle_translation") {
      for (std::size_t i = 0; i < n; ++i)
        if (bc.region.contains({p_.x[3 * i], p_.x[3 * i + 1], p_.x[3 * i + 2]})) {
          for (int d = 0; d < 3; ++d) p_.v[3 * i + d] = bc.velocity[d] * factor;
          std::fill_n(&p_.C[9 * i], 9, 0.0);
        }
    } else if (bc.type == "enforce_particle_velocity_rotation") {
      const double w[3] = {bc.angular_velocity[0] * factor, bc.angular_velocity[1] * factor,
                           bc.angular_velocity[2] * factor};
      for (std::size_t i = 0; i < n; ++i) {
        double r[3];
        for (int d = 0; d < 3; ++d) r[d] = p_.x[3 * i + d] - bc.point[d];
        const double h = dot3(r, bc.normal.data());
        double radial[3];
        for (int d = 0; d < 3; ++d) radial[d] = r[d] - h * bc.normal[d];
        if (std::abs(h) > bc.half_height || dot3(radial, radial) > bc.radius * bc.radius) continue;
        const double wxr[3] = {w[1] * r[2] - w[2] * r[1], w[2] * r[0] - w[0] * r[2],
                               w[0] * r[1] - w[1] * r[0]};
        for (int d = 0; d < 3; ++d) p_.v[3 * i + d] = bc.velocity[d] * factor + wxr[d];
        // Rigid velocity gradient: skew(w).
        const double S[9] = {0, -w[2], w[1], w[2], 0, -w[0], -w[1], w[0], 0};
        std::copy(S, S + 9, &p_.C[9 * i]);
      }
    }
  }
}

kernels::GuardArgs Solver::guard_args(double dt) {
  const auto nodes = spec_.nodes();
  kernels::GuardArgs a{};
  a.x = p_.x.data();
  a.v = p_.v.data();
  a.F = p_.F.data();
  for (int d = 0; d < 3; ++d) {
    a.lo[d] = spec_.lo[d];
    a.nodes[d] = nodes[d];
  }
  a.dx = spec_.dx;
  a.dt = dt;
  a.limit = opt_.max_cells_per_substep * spec_.dx;
  a.remove_outside = opt_.remove_outside;
  return a;
}

void Solver::check_and_confine(double t, double dt) {
  const long n = static_cast<long>(p_.size());
  status_.resize(static_cast<std::size_t>(n));
  std::uint8_t* status = status_.data();
  if (!guarded_) {
    const kernels::GuardArgs a = guard_args(dt);
    exec::parallel_for(n, [&](long i) { status[i] = kernels::guard_particle(a, i); });
  }
  guarded_ = false;
  long long bad = 0, removed = 0, clamped = 0;
  for (long i = 0; i < n; ++i) {
    bad += status[i] == kernels::kUnstable;
    removed += status[i] == kernels::kRemove;
    clamped += status[i] == kernels::kClamped;
  }
  long long counts[3] = {bad, removed, clamped};
  parallel::sum_in_place(comm_, counts, 3);
  if (counts[0] > 0) {
    // Up to 3 unstable particles per rank (id, x, y, z, speed); every rank learns them all, so
    // every rank throws the same message.
    std::vector<double> report;
    for (long i = 0; i < n && report.size() < 15; ++i)
      if (status[i] == kernels::kUnstable) {
        const double* x = &p_.x[3 * i];
        report.insert(report.end(), {static_cast<double>(p_.id[i]), x[0], x[1], x[2],
                                     std::sqrt(dot3(&p_.v[3 * i], &p_.v[3 * i]))});
      }
    report.resize(15, std::numeric_limits<double>::quiet_NaN());
    if (bad < 3)
      for (long long k = bad; k < 3; ++k) report[5 * k] = -1;
    const std::vector<double> all = parallel::all_gather(comm_, report);
    std::string where;
    int shown = 0;
    for (std::size_t k = 0; k < all.size() / 5 && shown < 5; ++k) {
      if (!(all[5 * k] >= 0)) continue;
      where += fmt::format("{}id {} at ({:.4g}, {:.4g}, {:.4g}) m, speed {:.3g} m/s",
                           shown ? "; " : "", static_cast<long long>(all[5 * k]), all[5 * k + 1],
                           all[5 * k + 2], all[5 * k + 3], all[5 * k + 4]);
      ++shown;
    }
    throw InstabilityError(fmt::format(
        "MPM instability at t = {:.6g} s (substep {:.3g} s): {} particle(s) non-finite or moving "
        "more than {} cell(s) in one substep: {}. Reduce simulation.dt or use mpm.substep = "
        "\"adaptive\" with a smaller mpm.cfl / mpm.wave_cfl",
        t + dt, dt, counts[0], opt_.max_cells_per_substep, where));
  }
  if (removed > 0) {
    std::vector<std::uint8_t> keep(static_cast<std::size_t>(n));
    for (long i = 0; i < n; ++i) keep[i] = status[i] != kernels::kRemove;
    p_.compact(keep);
  }
  removed_total_ += counts[1];
  clamped_total_ += counts[2];
}

void Solver::migrate() {
  if (size_ == 1) return;
  dest_.resize(p_.size());
  int* dest = dest_.data();
  exec::parallel_for(static_cast<long>(p_.size()),
                     [&](long i) { dest[i] = owner_of(&p_.x[3 * i]); });
  long long total = static_cast<long long>(redistribute(comm_, p_, dest_));
  migrated_total_ += parallel::sum_of(comm_, total);
}

long long Solver::count() const {
  return parallel::sum_of(comm_, static_cast<long long>(p_.size()));
}

double Solver::total_mass() const {
  parallel::ExactSum s;
  for (double m : p_.mass) s.add(m);
  double out = 0;
  parallel::Reducer(comm_).sum(&s, &out, 1);
  return out;
}

std::array<double, 3> Solver::total_momentum() const {
  parallel::ExactSum s[3];
  for (std::size_t i = 0; i < p_.size(); ++i)
    for (int d = 0; d < 3; ++d) s[d].add(p_.mass[i] * p_.v[3 * i + d]);
  std::array<double, 3> out{};
  parallel::Reducer(comm_).sum(s, out.data(), 3);
  return out;
}

double Solver::kinetic_energy() const {
  parallel::ExactSum s;
  for (std::size_t i = 0; i < p_.size(); ++i)
    s.add(0.5 * p_.mass[i] * dot3(&p_.v[3 * i], &p_.v[3 * i]));
  double out = 0;
  parallel::Reducer(comm_).sum(&s, &out, 1);
  return out;
}

}  // namespace gen4d::mpm
