#include "mpm/Solver.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "parallel/Reduce.hpp"

namespace gen4d::mpm {

namespace {

// Adding and subtracting 1.5 * 2^52 rounds a double of magnitude below 2^51 to the nearest
// integer (ties to even) in the default rounding mode; cheaper than std::nearbyint.
constexpr double kRound = 6755399441055744.0;
inline double round_int(double c) {
  return (c + kRound) - kRound;
}

// Contributions are at most 2^kQuantumBits quanta, so 2^(53 - kQuantumBits) of them can meet
// at one node before a sum could lose exactness.
constexpr int kQuantumBits = 40;

//! Inverse quantum (a power of two) for contributions bounded by `bound`.
double inverse_quantum(double bound) {
  if (!(bound > 0) || !std::isfinite(bound)) return 1.0;
  return std::ldexp(1.0, kQuantumBits - std::ilogb(bound) - 1);
}

//! Quadratic B-spline stencil of a particle: the first of its 3x3x3 nodes relative to the
//! ghosted box, the particle's offset from it in cells (fx in [0.5, 1.5)) and the weights.
struct Stencil {
  long base[3];
  double fx[3], w[3][3];

  Stencil(const double* xp, const GridSpec& g, const parallel::Box& box) {
    for (int a = 0; a < 3; ++a) {
      const double X = (xp[a] - g.lo[a]) / g.dx;
      const long b = static_cast<long>(std::floor(X - 0.5));
      const double f = X - static_cast<double>(b);
      fx[a] = f;
      w[a][0] = 0.5 * (1.5 - f) * (1.5 - f);
      w[a][1] = 0.75 - (f - 1.0) * (f - 1.0);
      w[a][2] = 0.5 * (f - 0.5) * (f - 0.5);
      base[a] = b - box.start[a];
    }
  }
};

inline bool active(const BoundaryConfig& b, double t) {
  return t >= b.start && t < b.end;
}

inline double dot3(const double* a, const double* b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

//! The affine matrix P2G transfers: C blended towards its skew part by r (RPIC damping), or
//! zero for r < 0 (PIC).
inline void transfer_affine(const double* C, double r, double* out) {
  if (r == 0) {
    std::copy_n(C, 9, out);
    return;
  }
  if (r < 0) {
    std::fill_n(out, 9, 0.0);
    return;
  }
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b)
      out[3 * a + b] = (1 - r) * C[3 * a + b] + 0.5 * r * (C[3 * a + b] - C[3 * b + a]);
}

}  // namespace

Solver::Solver(MPI_Comm comm, const GridSpec& grid, MaterialSet materials,
               const SolverOptions& options, std::vector<BoundaryConfig> boundaries)
    : comm_(comm),
      spec_(grid),
      materials_(std::move(materials)),
      opt_(options),
      bcs_(std::move(boundaries)) {
  MPI_Comm_rank(comm_, &rank_);
  MPI_Comm_size(comm_, &size_);
  for (int a = 0; a < 3; ++a)
    if (spec_.cells[a] < 2 * opt_.boundary_layers + 3)
      throw InputError(
          fmt::format("mpm grid: {} cells along axis {} is too few; it needs at least {} (2 x "
                      "mpm.boundary_layers + 3)",
                      spec_.cells[a], "xyz"[a], 2 * opt_.boundary_layers + 3));
}

Solver::~Solver() = default;

int Solver::owner_of(const double* x) const {
  long n[3];
  const auto nodes = spec_.nodes();
  for (int a = 0; a < 3; ++a) {
    const double X = (x[a] - spec_.lo[a]) / spec_.dx;
    n[a] = std::clamp(static_cast<long>(std::floor(X + 0.5)), 1L, nodes[a] - 2);
  }
  return grid_->owner_of(n[0], n[1], n[2]);
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
    MPI_Allreduce(MPI_IN_PLACE, hist.data(), static_cast<int>(hist.size()), MPI_LONG_LONG, MPI_SUM,
                  comm_);
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
  halo1_ = std::make_unique<parallel::Halo>(*grid_, 1);
  halo3_ = std::make_unique<parallel::Halo>(*grid_, 3);
  const std::size_t ng = static_cast<std::size_t>(grid_->ghosted_nodes().size());
  mass_.assign(ng, 0.0);
  mom_.assign(3 * ng, 0.0);
  vel_.assign(3 * ng, 0.0);

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
    MPI_Allreduce(MPI_IN_PLACE, &lo, 1, MPI_DOUBLE, MPI_MIN, comm_);
    MPI_Allreduce(MPI_IN_PLACE, &hi, 1, MPI_DOUBLE, MPI_MAX, comm_);
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
  double most[2] = {0, materials_.state_wave_speed(p_.size(), p_.material.data(), p_.state.data())};
  for (std::size_t i = 0; i < p_.size(); ++i) {
    const double* v = &p_.v[3 * i];
    most[0] = std::max(most[0], v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  }
  MPI_Allreduce(MPI_IN_PLACE, most, 2, MPI_DOUBLE, MPI_MAX, comm_);
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
    halo1_->scatter_add(mass_.data());
    halo3_->scatter_add(mom_.data());
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
  const std::size_t n = p_.size();
  const double dx = spec_.dx, inv_dx = 1.0 / dx;
  const double stress_scale = -dt * 4.0 * inv_dx * inv_dx;
  // Quanta from the global largest contributions.
  const double rpic = opt_.rpic_damping;
  double bound[2] = {0, 0};
  for (std::size_t i = 0; i < n; ++i) {
    const double m = p_.mass[i];
    bound[0] = std::max(bound[0], m);
    double mv = 0, a = 0, C[9];
    transfer_affine(&p_.C[9 * i], rpic, C);
    for (int d = 0; d < 3; ++d) mv = std::max(mv, std::abs(p_.v[3 * i + d]));
    for (int k = 0; k < 9; ++k)
      a = std::max(a, std::abs(stress_scale * p_.vol0[i] * tau_[9 * i + k]) + std::abs(m * C[k]));
    bound[1] = std::max(bound[1], m * mv + 3 * a * 1.5 * dx);
  }
  MPI_Allreduce(MPI_IN_PLACE, bound, 2, MPI_DOUBLE, MPI_MAX, comm_);
  const double inv_qm = inverse_quantum(bound[0]), inv_qp = inverse_quantum(bound[1]);
  quantum_mass_ = 1.0 / inv_qm;
  quantum_mom_ = 1.0 / inv_qp;

  std::fill(mass_.begin(), mass_.end(), 0.0);
  std::fill(mom_.begin(), mom_.end(), 0.0);
  const parallel::Box& gb = grid_->ghosted_nodes();
  const long gx = gb.count[0], gy = gb.count[1];
  for (std::size_t i = 0; i < n; ++i) {
    if (p_.flag[i] & 1) continue;
    const Stencil st(&p_.x[3 * i], spec_, gb);
    const long* base = st.base;
    const double* fx = st.fx;
    const auto& w = st.w;
    const double m = p_.mass[i];
    const double s = stress_scale * p_.vol0[i];
    double A[9], mv[3], C[9];
    transfer_affine(&p_.C[9 * i], rpic, C);
    for (int k = 0; k < 9; ++k) A[k] = s * tau_[9 * i + k] + m * C[k];
    for (int d = 0; d < 3; ++d) mv[d] = m * p_.v[3 * i + d];
    for (int c = 0; c < 3; ++c) {
      const double dz = (c - fx[2]) * dx;
      for (int b = 0; b < 3; ++b) {
        const double dy = (b - fx[1]) * dx;
        const double wzy = w[2][c] * w[1][b];
        const long row = ((base[2] + c) * gy + (base[1] + b)) * gx + base[0];
        // Affine momentum at this row: mv + A (dpos), dpos = (dx0, dy, dz).
        double r[3];
        for (int d = 0; d < 3; ++d) r[d] = mv[d] + A[3 * d + 1] * dy + A[3 * d + 2] * dz;
        for (int a = 0; a < 3; ++a) {
          const double dxa = (a - fx[0]) * dx;
          const double weight = wzy * w[0][a];
          const std::size_t idx = static_cast<std::size_t>(row + a);
          mass_[idx] += round_int(weight * m * inv_qm);
          double* P = &mom_[3 * idx];
          P[0] += round_int(weight * (r[0] + A[0] * dxa) * inv_qp);
          P[1] += round_int(weight * (r[1] + A[3] * dxa) * inv_qp);
          P[2] += round_int(weight * (r[2] + A[6] * dxa) * inv_qp);
        }
      }
    }
  }
}

void Solver::grid_update(double t, double dt) {
  const parallel::Box& gb = grid_->ghosted_nodes();
  const auto nodes = spec_.nodes();
  const int L = opt_.boundary_layers;
  bool walls = true;
  bool has_box_entry = false;
  for (const auto& b : bcs_)
    if (b.type == "bounding_box") {
      has_box_entry = true;
      walls = active(b, t);
    }
  if (!has_box_entry) walls = true;
  const double* g = opt_.gravity.data();
  const double damp = opt_.damping > 0 ? 1.0 / (1.0 + opt_.damping * dt) : 1.0;
  const double scale_v = opt_.grid_velocity_scale;
  // Cuboid boxes at time t, and whether each one's reset window holds t.
  std::vector<BoxRegion> boxes(bcs_.size());
  std::vector<char> resetting(bcs_.size(), 0);
  for (std::size_t b = 0; b < bcs_.size(); ++b) {
    if (bcs_[b].type != "cuboid") continue;
    boxes[b] = cuboid_region(bcs_[b], t);
    resetting[b] = t >= bcs_[b].end && t < bcs_[b].end + bcs_[b].reset_duration;
  }
  for (long k = 0; k < gb.count[2]; ++k)
    for (long j = 0; j < gb.count[1]; ++j)
      for (long i = 0; i < gb.count[0]; ++i) {
        const std::size_t n = static_cast<std::size_t>((k * gb.count[1] + j) * gb.count[0] + i);
        double* v = &vel_[3 * n];
        const double m = mass_[n] * quantum_mass_;
        if (!(m > 0)) {
          v[0] = v[1] = v[2] = 0;
          continue;
        }
        const double inv_m = quantum_mom_ / m;
        for (int d = 0; d < 3; ++d) v[d] = mom_[3 * n + d] * inv_m + dt * g[d];
        if (scale_v != 1)
          for (int d = 0; d < 3; ++d) v[d] *= scale_v;
        if (damp != 1)
          for (int d = 0; d < 3; ++d) v[d] *= damp;
        const long idx[3] = {gb.start[0] + i, gb.start[1] + j, gb.start[2] + k};
        const double xi[3] = {spec_.lo[0] + idx[0] * spec_.dx, spec_.lo[1] + idx[1] * spec_.dx,
                              spec_.lo[2] + idx[2] * spec_.dx};
        for (std::size_t b = 0; b < bcs_.size(); ++b) {
          const BoundaryConfig& bc = bcs_[b];
          if (resetting[b]) {
            v[0] = v[1] = v[2] = 0;
            continue;
          }
          if (!active(bc, t)) continue;
          if (bc.type == "cuboid") {
            if (boxes[b].contains({xi[0], xi[1], xi[2]}))
              for (int d = 0; d < 3; ++d) v[d] = bc.velocity[d];
          } else if (bc.type == "surface_collider") {
            const double* nrm = bc.normal.data();
            const double dist = (xi[0] - bc.point[0]) * nrm[0] + (xi[1] - bc.point[1]) * nrm[1] +
                                (xi[2] - bc.point[2]) * nrm[2];
            if (dist > 0 && !(dist < bc.soft_width)) continue;
            // Blend weight of a soft collider's outer band (1 on and inside the plane).
            const double wb = dist > 0 ? 1.0 - dist / bc.soft_width : 1.0;
            if (bc.surface == "sticky") {
              for (int d = 0; d < 3; ++d) v[d] -= wb * v[d];
              continue;
            }
            const double vn = dot3(v, nrm);
            if (bc.surface == "cut") {
              // Inside the cut: no normal velocity, cut_scale of the rest; elsewhere: stop.
              const bool in_cut = bc.region.contains({xi[0], xi[1], xi[2]});
              for (int d = 0; d < 3; ++d) {
                const double target = in_cut ? bc.cut_scale * (v[d] - vn * nrm[d]) : 0.0;
                v[d] = wb == 1.0 ? target : v[d] + wb * (target - v[d]);
              }
              continue;
            }
            if (bc.surface == "separate" && vn >= 0) continue;
            double vt[3];
            for (int d = 0; d < 3; ++d) vt[d] = v[d] - vn * nrm[d];
            const double vtn = std::sqrt(dot3(vt, vt));
            // Coulomb: the tangential speed drops by friction times the normal speed removed.
            const double scale =
                vtn > 0 ? std::max(0.0, 1.0 - bc.friction * std::abs(vn) / vtn) : 0.0;
            if (wb == 1.0)
              for (int d = 0; d < 3; ++d) v[d] = vt[d] * scale;
            else
              for (int d = 0; d < 3; ++d) v[d] += wb * (vt[d] * scale - v[d]);
          }
        }
        if (walls)
          for (int d = 0; d < 3; ++d) {
            if (idx[d] < L && v[d] < 0) v[d] = 0;
            if (idx[d] > nodes[d] - 1 - L && v[d] > 0) v[d] = 0;
          }
      }
}

void Solver::g2p(double t, double dt) {
  const std::size_t n = p_.size();
  const double dx = spec_.dx, inv_dx = 1.0 / dx;
  const parallel::Box& gb = grid_->ghosted_nodes();
  const long gx = gb.count[0], gy = gb.count[1];
  bool any_release = false;
  for (const auto& b : bcs_) any_release |= b.type == "release_particles_sequentially";
  for (std::size_t i = 0; i < n; ++i) {
    if (any_release) {
      if (frozen(i, t + dt)) {
        p_.flag[i] |= 1;
        continue;
      }
      p_.flag[i] &= static_cast<std::uint8_t>(~1u);
    }
    if (p_.flag[i] & 1) continue;
    const Stencil st(&p_.x[3 * i], spec_, gb);
    const long* base = st.base;
    const double* fx = st.fx;
    const auto& w = st.w;
    double vn[3] = {0, 0, 0}, B[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
    for (int c = 0; c < 3; ++c) {
      const double dz = (c - fx[2]) * dx;
      for (int b = 0; b < 3; ++b) {
        const double dy = (b - fx[1]) * dx;
        const double wzy = w[2][c] * w[1][b];
        const long row = ((base[2] + c) * gy + (base[1] + b)) * gx + base[0];
        for (int a = 0; a < 3; ++a) {
          const double dxa = (a - fx[0]) * dx;
          const double weight = wzy * w[0][a];
          const double* vi = &vel_[3 * static_cast<std::size_t>(row + a)];
          for (int d = 0; d < 3; ++d) {
            const double wv = weight * vi[d];
            vn[d] += wv;
            B[3 * d + 0] += wv * dxa;
            B[3 * d + 1] += wv * dy;
            B[3 * d + 2] += wv * dz;
          }
        }
      }
    }
    const double cs = 4.0 * inv_dx * inv_dx;
    for (int k = 0; k < 9; ++k) p_.C[9 * i + k] = cs * B[k];
    for (int d = 0; d < 3; ++d) p_.v[3 * i + d] = vn[d];
  }
  particle_conditions(t, dt);
  for (std::size_t i = 0; i < n; ++i) {
    if (p_.flag[i] & 1) continue;
    double* xp = &p_.x[3 * i];
    const double* v = &p_.v[3 * i];
    for (int d = 0; d < 3; ++d) xp[d] += dt * v[d];
    advance_deformation(&p_.C[9 * i], dt, &p_.F[9 * i]);
  }
}

void Solver::particle_conditions(double t, double dt) {
  const std::size_t n = p_.size();
  for (const auto& bc : bcs_) {
    // Collective decisions only depend on t, identical on every rank.
    if (!active(bc, t)) continue;
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
          for (int d = 0; d < 3; ++d) p_.v[3 * i + d] += dt * bc.force[d] / region_mass;
    } else if (bc.type == "enforce_particle_translation") {
      for (std::size_t i = 0; i < n; ++i)
        if (bc.region.contains({p_.x[3 * i], p_.x[3 * i + 1], p_.x[3 * i + 2]})) {
          for (int d = 0; d < 3; ++d) p_.v[3 * i + d] = bc.velocity[d];
          std::fill_n(&p_.C[9 * i], 9, 0.0);
        }
    } else if (bc.type == "enforce_particle_velocity_rotation") {
      const double* w = bc.angular_velocity.data();
      for (std::size_t i = 0; i < n; ++i) {
        double r[3];
        for (int d = 0; d < 3; ++d) r[d] = p_.x[3 * i + d] - bc.point[d];
        const double h = dot3(r, bc.normal.data());
        double radial[3];
        for (int d = 0; d < 3; ++d) radial[d] = r[d] - h * bc.normal[d];
        if (std::abs(h) > bc.half_height || dot3(radial, radial) > bc.radius * bc.radius) continue;
        const double wxr[3] = {w[1] * r[2] - w[2] * r[1], w[2] * r[0] - w[0] * r[2],
                               w[0] * r[1] - w[1] * r[0]};
        for (int d = 0; d < 3; ++d) p_.v[3 * i + d] = bc.velocity[d] + wxr[d];
        // Rigid velocity gradient: skew(w).
        const double S[9] = {0, -w[2], w[1], w[2], 0, -w[0], -w[1], w[0], 0};
        std::copy(S, S + 9, &p_.C[9 * i]);
      }
    }
  }
}

void Solver::check_and_confine(double t, double dt) {
  const std::size_t n = p_.size();
  const auto nodes = spec_.nodes();
  const double limit = opt_.max_cells_per_substep * spec_.dx;
  // Unstable particles: up to 3 reported per rank.
  long long bad = 0;
  std::vector<double> report;  // id, x, y, z, speed
  std::vector<std::uint8_t> keep;
  long long removed = 0, clamped = 0;
  for (std::size_t i = 0; i < n; ++i) {
    double* x = &p_.x[3 * i];
    double* v = &p_.v[3 * i];
    bool finite = true;
    for (int d = 0; d < 3; ++d) finite &= std::isfinite(x[d]) && std::isfinite(v[d]);
    for (int k = 0; k < 9; ++k) finite &= std::isfinite(p_.F[9 * i + k]);
    const double speed = std::sqrt(dot3(v, v));
    if (!finite || speed * dt > limit) {
      if (bad++ < 3)
        report.insert(report.end(), {static_cast<double>(p_.id[i]), x[0], x[1], x[2], speed});
      continue;
    }
    bool outside = false;
    for (int a = 0; a < 3; ++a) {
      const double X = (x[a] - spec_.lo[a]) / spec_.dx;
      const double hi = static_cast<double>(nodes[a] - 2);
      if (X < 1.0 || X >= hi) outside = true;
    }
    if (!outside) continue;
    if (opt_.remove_outside) {
      if (keep.empty()) keep.assign(n, 1);
      keep[i] = 0;
      ++removed;
    } else {
      ++clamped;
      for (int a = 0; a < 3; ++a) {
        const double X = (x[a] - spec_.lo[a]) / spec_.dx;
        const double hi = static_cast<double>(nodes[a] - 2) - 1e-6;
        if (X < 1.0) {
          x[a] = spec_.lo[a] + spec_.dx;
          v[a] = std::max(v[a], 0.0);
        } else if (X >= hi) {
          x[a] = spec_.lo[a] + hi * spec_.dx;
          v[a] = std::min(v[a], 0.0);
        }
      }
    }
  }
  long long counts[3] = {bad, removed, clamped};
  MPI_Allreduce(MPI_IN_PLACE, counts, 3, MPI_LONG_LONG, MPI_SUM, comm_);
  if (counts[0] > 0) {
    // Every rank learns the reported particles, so every rank throws the same message.
    report.resize(15, std::numeric_limits<double>::quiet_NaN());
    if (bad < 3)
      for (long long k = bad; k < 3; ++k) report[5 * k] = -1;
    std::vector<double> all(15 * static_cast<std::size_t>(size_));
    MPI_Allgather(report.data(), 15, MPI_DOUBLE, all.data(), 15, MPI_DOUBLE, comm_);
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
  if (!keep.empty()) p_.compact(keep);
  removed_total_ += counts[1];
  clamped_total_ += counts[2];
}

void Solver::migrate() {
  const long long sent = static_cast<long long>(
      redistribute(comm_, p_, [&](std::size_t i) { return owner_of(&p_.x[3 * i]); }));
  long long total = sent;
  if (size_ > 1) MPI_Allreduce(MPI_IN_PLACE, &total, 1, MPI_LONG_LONG, MPI_SUM, comm_);
  migrated_total_ += total;
}

long long Solver::count() const {
  long long n = static_cast<long long>(p_.size());
  MPI_Allreduce(MPI_IN_PLACE, &n, 1, MPI_LONG_LONG, MPI_SUM, comm_);
  return n;
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
