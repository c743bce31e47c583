#include "elastogen/VoxelSystem.hpp"

#include <algorithm>
#include <stdexcept>
#include <utility>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "core/Error.hpp"

// The interior row loop is compiled for AVX-512 and AVX2 besides the baseline, picked at run
// time. Contraction into fused multiply-adds is off there, so every clone rounds each product
// and sum as the baseline does: results do not depend on the CPU that runs them.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define GEN4D_SWEEP_CLONES \
  __attribute__((target_clones("avx512f", "avx2", "default"), optimize("fp-contract=off")))
#else
#define GEN4D_SWEEP_CLONES
#endif

namespace gen4d::elastogen {

namespace {
//! out[q] = (A d)_q for the values q in [0, count) of a run of interior nodes starting at d.
GEN4D_SWEEP_CLONES void interior_run(const StencilCoefficients s, const double* d, long count,
                                     long Y, long Z, double* out) {
  for (long q = 0; q < count; ++q) out[q] = interior_value(s, d, q, Y, Z);
}
//! The same for cells of unequal edges.
GEN4D_SWEEP_CLONES void interior_run_axes(const AxisStencilCoefficients s, const double* d,
                                          long count, long Y, long Z, double* out) {
  for (long q = 0; q < count; ++q) out[q] = interior_value_axes(s, d, q, Y, Z);
}
}  // namespace

VoxelSystem::VoxelSystem(const parallel::NodeGrid& grid, const Vec3d& origin, const Vec3d& spacing,
                         std::vector<std::uint8_t> occupancy, const std::vector<double>& density,
                         const std::vector<BoxRegion>& held)
    : grid_(grid),
      origin_(origin),
      spacing_(spacing),
      h_(std::max({spacing[0], spacing[1], spacing[2]})),
      cubic_(spacing[0] == spacing[1] && spacing[1] == spacing[2]),
      occ_(std::move(occupancy)),
      slots_(density.size()) {
  for (std::uint8_t o : occ_)
    if (o > slots_)
      throw std::logic_error("VoxelSystem: occupancy names a material slot without a density");
  const Box& G = ghosted();
  const Box& C = cells();
  for (int m = 0; m < 8; ++m)
    corner_offset_[m] = static_cast<long>(
        G.index(G.start[0] + (m & 1), G.start[1] + ((m >> 1) & 1), G.start[2] + ((m >> 2) & 1)));
  // The interior 27-point stencil: neighbour (dx, dy, dz) collects K[l][m] from every voxel
  // holding both nodes.
  const HexStencil& hs = HexStencil::get();
  // The cell's Laplacian: the unit cube's times h for cubes, hx hy hz sum_d Kd / h_d^2 else.
  const double hx = spacing_[0], hy = spacing_[1], hz = spacing_[2], vol = hx * hy * hz;
  lap_scale_ = cubic_ ? h_ : 1.0;
  for (int l = 0; l < 8; ++l)
    for (int m = 0; m < 8; ++m)
      lap_[l][m] = cubic_ ? hs.K[l][m]
                          : vol * (hs.Kd[0][l][m] / (hx * hx) + hs.Kd[1][l][m] / (hy * hy) +
                                   hs.Kd[2][l][m] / (hz * hz));
  interior_stencil_.fill(0.0);
  for (int t = 0; t < 27; ++t)
    interior_offset_[t] =
        (t % 3 - 1) + (t / 3 % 3 - 1) * G.count[0] + (t / 9 - 1) * G.count[0] * G.count[1];
  for (int cell = 0; cell < 8; ++cell) {
    const int l = corner_in_cell(cell);
    const int a = cell & 1, b = (cell >> 1) & 1, c = (cell >> 2) & 1;
    for (int m = 0; m < 8; ++m) {
      // Corner m of that voxel sits at node offset (a - 1 + mx, b - 1 + my, c - 1 + mz).
      const int dx = a - 1 + (m & 1), dy = b - 1 + ((m >> 1) & 1), dz = c - 1 + ((m >> 2) & 1);
      interior_stencil_[(dz + 1) * 9 + (dy + 1) * 3 + (dx + 1)] += lap_[l][m];
    }
  }
  // The stencil's 27 coefficients take one value per class (centre, 6 faces, 12 edges,
  // 8 corners) by the voxel's symmetry; the interior kernel sums each class's neighbours
  // first (23 adds and 4 multiplies instead of 27 of each).
  std::array<int, 4> members{};
  for (int t = 0; t < 27; ++t) {
    const int cls = (t % 3 != 1) + (t / 3 % 3 != 1) + (t / 9 != 1);
    stencil_class_[cls] += interior_stencil_[t];
    ++members[cls];
  }
  for (int c = 0; c < 4; ++c) stencil_class_[c] /= members[c];
  // Unequal edges keep the reflection symmetry only: one class per set of axes offset.
  {
    constexpr int kSlot[8] = {0, 1, 2, 4, 3, 5, 6, 7};  // offset axes bits -> coefficient
    std::array<int, 8> count{};
    for (int t = 0; t < 27; ++t) {
      const int bits = (t % 3 != 1) | (t / 3 % 3 != 1) << 1 | (t / 9 != 1) << 2;
      stencil_axes_[kSlot[bits]] += interior_stencil_[t];
      ++count[kSlot[bits]];
    }
    for (int c = 0; c < 8; ++c) stencil_axes_[c] /= count[c];
  }
  for (int m = 0; m < 8; ++m) interior_mass_ += 0.125 * (density.at(0) * hx * hy * hz);
  adj_.assign(G.size(), 0);
  mass_.assign(G.size(), 0.0);
  free_.assign(G.size(), 0);
  fixed_.assign(G.size(), 0);
  std::vector<double> cell_mass(density.size());
  for (std::size_t s = 0; s < density.size(); ++s) cell_mass[s] = density[s] * hx * hy * hz;
  const Box& O = owned();
  long local_free = 0, local_solid = 0;
  for (long k = O.start[2]; k < O.start[2] + O.count[2]; ++k)
    for (long j = O.start[1]; j < O.start[1] + O.count[1]; ++j)
      for (long i = O.start[0]; i < O.start[0] + O.count[0]; ++i) {
        const std::size_t n = G.index(i, j, k);
        for (int cell = 0; cell < 8; ++cell) {
          const long ci = i - 1 + (cell & 1), cj = j - 1 + ((cell >> 1) & 1),
                     ck = k - 1 + ((cell >> 2) & 1);
          if (solid(ci, cj, ck)) {
            adj_[n] |= static_cast<std::uint8_t>(1u << cell);
            mass_[n] += 0.125 * cell_mass[occ_[C.index(ci, cj, ck)] - 1u];
          }
        }
        bool is_fixed = false;
        const auto p = rest_position(i, j, k);
        for (const auto& r : held) is_fixed = is_fixed || r.contains({p[0], p[1], p[2]});
        fixed_[n] = adj_[n] != 0 && is_fixed;
        free_[n] = adj_[n] != 0 && !is_fixed;
        local_free += free_[n];
      }
  const Box& oc = grid_.owned_cells();
  for (long k = oc.start[2]; k < oc.start[2] + oc.count[2]; ++k)
    for (long j = oc.start[1]; j < oc.start[1] + oc.count[1]; ++j)
      for (long i = oc.start[0]; i < oc.start[0] + oc.count[0]; ++i)
        local_solid += occ_[C.index(i, j, k)] != 0;
  // Masks and masses of ghost nodes come from their owners.
  parallel::Halo halo(grid_, 1);
  std::vector<double> tmp(G.size());
  for (std::size_t n = 0; n < tmp.size(); ++n) tmp[n] = free_[n] + 2.0 * fixed_[n];
  halo.gather(tmp.data());
  for (std::size_t n = 0; n < tmp.size(); ++n) {
    const int flags = static_cast<int>(tmp[n]);
    free_[n] = flags & 1;
    fixed_[n] = (flags >> 1) & 1;
  }
  halo.gather(mass_.data());
  parallel::Reducer red(grid_.comm());
  global_free_ = red.sum(static_cast<long long>(local_free));
  global_solid_ = red.sum(static_cast<long long>(local_solid));
}

void VoxelSystem::add_point_masses(const std::vector<PointMassConfig>& masses) {
  if (masses.empty()) return;
  const Box& G = ghosted();
  const std::vector<double> own = mass_;  // shares follow the body's own masses
  std::vector<parallel::ExactSum> local(masses.size());
  std::vector<long long> nodes(masses.size(), 0);
  for_owned(owned(), G, [&](std::size_t n, long i, long j, long k) {
    if (own[n] == 0.0) return;
    const auto p = rest_position(i, j, k);
    for (std::size_t e = 0; e < masses.size(); ++e)
      if (masses[e].region.contains({p[0], p[1], p[2]})) {
        local[e].add(own[n]);
        ++nodes[e];
      }
  });
  std::vector<double> total(masses.size());
  parallel::Reducer red(grid_.comm());
  red.sum(local.data(), total.data(), local.size());
  for (std::size_t e = 0; e < masses.size(); ++e)
    if (red.sum(nodes[e]) == 0)
      throw InputError(
          fmt::format("{}: [[point_mass]] region lo = [{}], hi = [{}] holds no node of the object",
                      masses[e].where, fmt::join(masses[e].region.lo, ", "),
                      fmt::join(masses[e].region.hi, ", ")));
  for_owned(owned(), G, [&](std::size_t n, long i, long j, long k) {
    if (own[n] == 0.0) return;
    const auto p = rest_position(i, j, k);
    for (std::size_t e = 0; e < masses.size(); ++e)
      if (masses[e].region.contains({p[0], p[1], p[2]}))
        mass_[n] += masses[e].mass * (own[n] / total[e]);
  });
  parallel::Halo halo(grid_, 1);
  halo.gather(mass_.data());
}

bool VoxelSystem::solid(long ci, long cj, long ck) const {
  const Box& C = cells();
  if (!C.contains(ci, cj, ck)) return false;
  return occ_[C.index(ci, cj, ck)] != 0;
}

template <class Emit>
void VoxelSystem::operator_rows(double k, double inv_dt2, const double* delta, Emit&& emit) const {
  const Box& G = ghosted();
  const Box& O = owned();
  const double kh = k * lap_scale_;
  const long gx = G.count[0], gxy = G.count[0] * G.count[1];
  const StencilCoefficients sc{interior_mass_ * inv_dt2 + kh * stencil_class_[0],
                               kh * stencil_class_[1], kh * stencil_class_[2],
                               kh * stencil_class_[3]};
  AxisStencilCoefficients sa{interior_mass_ * inv_dt2 + kh * stencil_axes_[0],
                             kh * stencil_axes_[1],
                             kh * stencil_axes_[2],
                             kh * stencil_axes_[3],
                             kh * stencil_axes_[4],
                             kh * stencil_axes_[5],
                             kh * stencil_axes_[6],
                             kh * stencil_axes_[7]};
  GeneralStencil gs;
  for (int l = 0; l < 8; ++l)
    for (int m = 0; m < 8; ++m) gs.kK[l][m] = kh * lap_[l][m];
  for (int m = 0; m < 8; ++m) gs.corner_offset[m] = corner_offset_[m];
  gs.gx = gx;
  gs.gxy = gxy;
  const long Y = 3 * gx, Z = 3 * gxy;
  // Interior: eight solid voxels of slot 0's density (other nodes take the general rows).
  auto interior = [&](std::size_t n) {
    return free_[n] && adj_[n] == 0xFF && mass_[n] == interior_mass_;
  };
  parallel_box_rows(O, [&](long j, long kk) {
    double row[3 * 64];  // one run's values at a time (runs are cut at 64 nodes)
    const long i_end = O.start[0] + O.count[0];
    for (long i = O.start[0]; i < i_end;) {
      const std::size_t n = G.index(i, j, kk);
      if (interior(n)) {
        // A run of interior nodes along x, as one flat array of interleaved xyz values (the
        // same coefficient acts on all three components), so the loop vectorises. The
        // arithmetic of a value depends on its neighbourhood only, not on the run.
        long len = 1;
        while (len < 64 && i + len < i_end && interior(n + len)) ++len;
        if (cubic_)
          interior_run(sc, delta + 3 * n, 3 * len, Y, Z, row);
        else
          interior_run_axes(sa, delta + 3 * n, 3 * len, Y, Z, row);
        emit(n, len, static_cast<const double*>(row));
        i += len;
        continue;
      }
      double acc[3] = {0, 0, 0};
      if (free_[n])
        for (int d = 0; d < 3; ++d)
          acc[d] = general_value(gs, delta, static_cast<long>(n), adj_[n], mass_[n] * inv_dt2, d);
      emit(n, 1, static_cast<const double*>(acc));
      ++i;
    }
  });
}

void VoxelSystem::apply(double k, double inv_dt2, const double* delta, double* out) const {
  operator_rows(k, inv_dt2, delta, [&](std::size_t n, long len, const double* v) {
    double* o = out + 3 * n;
    for (long q = 0; q < 3 * len; ++q) o[q] = v[q];
  });
}

void VoxelSystem::jacobi_sweep(double k, double inv_dt2, double omega, const double* r,
                               const double* diag, const double* d_old, double* d_new,
                               double* res) const {
  operator_rows(k, inv_dt2, d_old, [&](std::size_t n0, long len, const double* v) {
    for (long a = 0; a < len; ++a) {
      const std::size_t n = n0 + a;
      if (!free_[n]) {
        for (int d = 0; d < 3; ++d) d_new[3 * n + d] = d_old[3 * n + d];
        continue;
      }
      const double w = omega / diag[n];
      for (int d = 0; d < 3; ++d) {
        const double rr = r[3 * n + d] - v[3 * a + d];
        if (res) res[3 * n + d] = rr;
        d_new[3 * n + d] = d_old[3 * n + d] + rr * w;
      }
    }
  });
}

JacobiSweepKernel VoxelSystem::jacobi_kernel(double k, double inv_dt2, double omega,
                                             const double* r, const double* diag,
                                             const double* mass, const std::uint8_t* free,
                                             const std::uint8_t* adj, const double* d_old,
                                             double* d_new, double* res) const {
  const Box& G = ghosted();
  const Box& O = owned();
  const double kh = k * lap_scale_;
  JacobiSweepKernel kern;
  kern.r = r;
  kern.diag = diag;
  kern.mass = mass;
  kern.free = free;
  kern.adj = adj;
  kern.d_old = d_old;
  kern.d_new = d_new;
  kern.res = res;
  kern.s = {interior_mass_ * inv_dt2 + kh * stencil_class_[0], kh * stencil_class_[1],
            kh * stencil_class_[2], kh * stencil_class_[3]};
  kern.axes = !cubic_;
  kern.sa = {interior_mass_ * inv_dt2 + kh * stencil_axes_[0],
             kh * stencil_axes_[1],
             kh * stencil_axes_[2],
             kh * stencil_axes_[3],
             kh * stencil_axes_[4],
             kh * stencil_axes_[5],
             kh * stencil_axes_[6],
             kh * stencil_axes_[7]};
  for (int l = 0; l < 8; ++l)
    for (int m = 0; m < 8; ++m) kern.g.kK[l][m] = kh * lap_[l][m];
  for (int m = 0; m < 8; ++m) kern.g.corner_offset[m] = corner_offset_[m];
  kern.g.gx = G.count[0];
  kern.g.gxy = G.count[0] * G.count[1];
  kern.interior_mass = interior_mass_;
  kern.inv_dt2 = inv_dt2;
  kern.omega = omega;
  kern.o0 = O.start[0] - G.start[0];
  kern.o1 = O.start[1] - G.start[1];
  kern.o2 = O.start[2] - G.start[2];
  kern.n0 = O.count[0];
  kern.n1 = O.count[1];
  kern.n2 = O.count[2];
  kern.Y = 3 * kern.g.gx;
  kern.Z = 3 * kern.g.gxy;
  return kern;
}

void VoxelSystem::diagonal(double k, double inv_dt2, std::vector<double>& diag) const {
  const Box& G = ghosted();
  const Box& O = owned();
  diag.assign(G.size(), 1.0);
  for (long kk = O.start[2]; kk < O.start[2] + O.count[2]; ++kk)
    for (long j = O.start[1]; j < O.start[1] + O.count[1]; ++j)
      for (long i = O.start[0]; i < O.start[0] + O.count[0]; ++i) {
        const std::size_t n = G.index(i, j, kk);
        if (!free_[n]) continue;
        double d = mass_[n] * inv_dt2;
        for (int cell = 0; cell < 8; ++cell) {
          if (!(adj_[n] >> cell & 1)) continue;
          const int l = corner_in_cell(cell);
          d += k * lap_scale_ * lap_[l][l];
        }
        diag[n] = d;
      }
}

}  // namespace gen4d::elastogen
