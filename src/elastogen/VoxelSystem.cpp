#include "elastogen/VoxelSystem.hpp"

#include <stdexcept>
#include <utility>

namespace gen4d::elastogen {

VoxelSystem::VoxelSystem(const parallel::NodeGrid& grid, const Vec3d& origin, double h,
                         std::vector<std::uint8_t> occupancy, const std::vector<double>& density,
                         const std::vector<BoxRegion>& held)
    : grid_(grid), origin_(origin), h_(h), occ_(std::move(occupancy)), slots_(density.size()) {
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
      interior_stencil_[(dz + 1) * 9 + (dy + 1) * 3 + (dx + 1)] += hs.K[l][m];
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
  for (int m = 0; m < 8; ++m) interior_mass_ += 0.125 * (density.at(0) * h * h * h);
  row_.assign(3 * G.count[0], 0.0);
  adj_.assign(G.size(), 0);
  mass_.assign(G.size(), 0.0);
  free_.assign(G.size(), 0);
  fixed_.assign(G.size(), 0);
  std::vector<double> cell_mass(density.size());
  for (std::size_t s = 0; s < density.size(); ++s) cell_mass[s] = density[s] * h * h * h;
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

bool VoxelSystem::solid(long ci, long cj, long ck) const {
  const Box& C = cells();
  if (!C.contains(ci, cj, ck)) return false;
  return occ_[C.index(ci, cj, ck)] != 0;
}

template <class Emit>
void VoxelSystem::operator_rows(double k, double inv_dt2, const double* delta, Emit&& emit) const {
  const HexStencil& s = HexStencil::get();
  const Box& G = ghosted();
  const Box& O = owned();
  const double kh = k * h_;
  const long gx = G.count[0], gxy = G.count[0] * G.count[1];
  // Interior coefficients: (m/dt^2 + k h c_centre), k h c_face, k h c_edge, k h c_corner.
  const double c0 = interior_mass_ * inv_dt2 + kh * stencil_class_[0];
  const double cf = kh * stencil_class_[1], ce = kh * stencil_class_[2],
               cc = kh * stencil_class_[3];
  const long Y = 3 * gx, Z = 3 * gxy;
  // Interior: eight solid voxels of slot 0's density (other nodes take the general rows).
  auto interior = [&](std::size_t n) {
    return free_[n] && adj_[n] == 0xFF && mass_[n] == interior_mass_;
  };
  for (long kk = O.start[2]; kk < O.start[2] + O.count[2]; ++kk)
    for (long j = O.start[1]; j < O.start[1] + O.count[1]; ++j) {
      const long i_end = O.start[0] + O.count[0];
      for (long i = O.start[0]; i < i_end;) {
        const std::size_t n = G.index(i, j, kk);
        if (interior(n)) {
          // A run of interior nodes along x, as one flat array of interleaved xyz values (the
          // same coefficient acts on all three components), so the loop vectorises. The
          // arithmetic of a value depends on its neighbourhood only, not on the run.
          long len = 1;
          while (i + len < i_end && interior(n + len)) ++len;
          // Nine neighbouring rows (dy, dz in -1..1) of the run, x offsets -3, 0, +3.
          const double* d = delta + 3 * n;
          const double *mm = d - Y - Z, *m0 = d - Z, *mp = d + Y - Z;
          const double *zm = d - Y, *zp = d + Y;
          const double *pm = d - Y + Z, *p0 = d + Z, *pp = d + Y + Z;
          double* o = row_.data();
          const long count = 3 * len;
          for (long q = 0; q < count; ++q) {
            const double faces = (d[q - 3] + d[q + 3]) + (zm[q] + zp[q]) + (m0[q] + p0[q]);
            const double edges = (zm[q - 3] + zm[q + 3] + zp[q - 3] + zp[q + 3]) +
                                 (m0[q - 3] + m0[q + 3] + p0[q - 3] + p0[q + 3]) +
                                 (mm[q] + mp[q] + pm[q] + pp[q]);
            const double corners = (mm[q - 3] + mm[q + 3] + mp[q - 3] + mp[q + 3]) +
                                   (pm[q - 3] + pm[q + 3] + pp[q - 3] + pp[q + 3]);
            o[q] = c0 * d[q] + cf * faces + ce * edges + cc * corners;
          }
          emit(n, len, o);
          i += len;
          continue;
        }
        double acc[3] = {0, 0, 0};
        if (free_[n]) {
          const double m = mass_[n] * inv_dt2;
          for (int dd = 0; dd < 3; ++dd) acc[dd] = m * delta[3 * n + dd];
          for (int cell = 0; cell < 8; ++cell) {
            if (!(adj_[n] >> cell & 1)) continue;
            const int a = cell & 1, b = (cell >> 1) & 1, c = (cell >> 2) & 1;
            const int l = corner_in_cell(cell);
            const long base = static_cast<long>(n) - (1 - a) - (1 - b) * gx - (1 - c) * gxy;
            for (int mm = 0; mm < 8; ++mm) {
              const double cf8 = kh * s.K[l][mm];
              const double* src = &delta[3 * (base + corner_offset_[mm])];
              acc[0] += cf8 * src[0];
              acc[1] += cf8 * src[1];
              acc[2] += cf8 * src[2];
            }
          }
        }
        emit(n, 1, acc);
        ++i;
      }
    }
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

void VoxelSystem::diagonal(double k, double inv_dt2, std::vector<double>& diag) const {
  const HexStencil& s = HexStencil::get();
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
          d += k * h_ * s.K[l][l];
        }
        diag[n] = d;
      }
}

}  // namespace gen4d::elastogen
