//! Per-rank view of the voxelized object: solid cells, node masks, lumped masses, and the
//! matrix-free stencils of ElastoGen (global-step operator and internal forces).
#pragma once

#include <array>
#include <cstdint>
#include <type_traits>
#include <utility>
#include <vector>

#include "core/Config.hpp"
#include "elastogen/BoxLoops.hpp"
#include "elastogen/HexStencil.hpp"
#include "elastogen/LocalKernels.hpp"
#include "elastogen/SweepKernel.hpp"
#include "parallel/Grid.hpp"
#include "parallel/Halo.hpp"
#include "parallel/Reduce.hpp"

namespace gen4d::elastogen {

using parallel::Box;

//! A node's neighbour voxel `cell` (bits: +x, +y, +z) has its lower corner at node - 1 + bits;
//! the node is that voxel's corner 7 - cell (the opposite bits).
inline int corner_in_cell(int cell) {
  return 7 - cell;
}

//! Calls f(linear index in G, i, j, k) for every node of the owned box O, x fastest.
template <class F>
void for_owned(const Box& O, const Box& G, F&& f) {
  for (long k = O.start[2]; k < O.start[2] + O.count[2]; ++k)
    for (long j = O.start[1]; j < O.start[1] + O.count[1]; ++j)
      for (long i = O.start[0]; i < O.start[0] + O.count[0]; ++i) f(G.index(i, j, k), i, j, k);
}

//! Node arrays live on the rank's ghosted node box (x-fastest, 3 dof interleaved for
//! vectors); cell arrays on the adjacent-cell box. Every owned-node result is computed
//! node by node from its 8 neighbouring voxels in a fixed order, so it does not depend on
//! the decomposition: the same arithmetic runs whatever the rank count.
class VoxelSystem {
 public:
  //! `occupancy` covers grid.adjacent_cells() (0 = empty, s + 1 = solid of material slot s),
  //! as voxelized by this rank, and `density` holds each slot's density; nodes inside a `held`
  //! region are not unknowns (fixed or moved on a prescribed path). Cells have the edges
  //! `spacing` (hx, hy, hz).
  VoxelSystem(const parallel::NodeGrid& grid, const Vec3d& origin, const Vec3d& spacing,
              std::vector<std::uint8_t> occupancy, const std::vector<double>& density,
              const std::vector<BoxRegion>& held);
  //! Cubic cells of edge h.
  VoxelSystem(const parallel::NodeGrid& grid, const Vec3d& origin, double h,
              std::vector<std::uint8_t> occupancy, const std::vector<double>& density,
              const std::vector<BoxRegion>& held)
      : VoxelSystem(grid, origin, Vec3d{h, h, h}, std::move(occupancy), density, held) {}

  const parallel::NodeGrid& grid() const { return grid_; }
  const Box& ghosted() const { return grid_.ghosted_nodes(); }
  const Box& owned() const { return grid_.owned_nodes(); }
  const Box& cells() const { return grid_.adjacent_cells(); }
  //! The largest cell edge (the edge of cubic cells).
  double h() const { return h_; }
  //! The cell edges along x, y, z.
  const Vec3d& spacing() const { return spacing_; }
  bool cubic() const { return cubic_; }
  const Vec3d& origin() const { return origin_; }
  std::array<double, 3> rest_position(long i, long j, long k) const {
    return {origin_[0] + spacing_[0] * i, origin_[1] + spacing_[1] * j,
            origin_[2] + spacing_[2] * k};
  }
  bool solid(long ci, long cj, long ck) const;
  const std::vector<std::uint8_t>& occupancy() const { return occ_; }
  std::size_t material_slots() const { return slots_; }

  //! Lumped mass per ghosted node (kg); 0 for nodes touching no solid voxel.
  const std::vector<double>& mass() const { return mass_; }
  //! 1 where the node is an unknown (touches a solid voxel and is not fixed), ghosts included.
  const std::vector<std::uint8_t>& free_mask() const { return free_; }
  const std::vector<std::uint8_t>& fixed_mask() const { return fixed_; }
  long global_solid_cells() const { return global_solid_; }
  long global_free_nodes() const { return global_free_; }

  //! Adds each [[point_mass]] to the lumped masses of the nodes of the object (those touching
  //! a solid voxel, held or not) whose rest position lies in its region, in proportion to
  //! their own mass. InputError naming the entry when its region holds no such node.
  //! Collective; call before the solvers take the masses.
  void add_point_masses(const std::vector<PointMassConfig>& masses);

  //! out = (M/dt^2 + k L) delta on free owned nodes, 0 elsewhere. delta's ghosts must be
  //! current. This is the seed's convolution / per-voxel multiply / transposed convolution
  //! fused into one 27-point stencil (the composition G^T k G for the trilinear voxel).
  void apply(double k, double inv_dt2, const double* delta, double* out) const;
  //! One damped-Jacobi sweep fused with the operator (one pass over memory): on free owned
  //! nodes rr = r - A d_old, d_new = d_old + rr * omega / diag, and res = rr when res is not
  //! null; held nodes copy d_old. d_old's ghosts must be current; d_old and d_new differ.
  void jacobi_sweep(double k, double inv_dt2, double omega, const double* r, const double* diag,
                    const double* d_old, double* d_new, double* res) const;
  //! Diagonal of the same operator on owned nodes (1 on non-free nodes).
  void diagonal(double k, double inv_dt2, std::vector<double>& diag) const;
  //! The pointwise sweep kernel over the owned values (3 per owned node) with these arrays
  //! (host or device pointers alike): what the GPU runs, and the CPU path's reference.
  JacobiSweepKernel jacobi_kernel(double k, double inv_dt2, double omega, const double* r,
                                  const double* diag, const double* mass, const std::uint8_t* free,
                                  const std::uint8_t* adj, const double* d_old, double* d_new,
                                  double* res) const;
  //! Neighbour-voxel bits per ghosted node (bit `cell` set where that voxel is solid).
  const std::vector<std::uint8_t>& adjacency() const { return adj_; }

  //! Internal forces f = -dE/dx on owned free nodes; returns the elastic energy of owned
  //! cells, unrounded. `stress(F, P)` returns the energy density and writes the first Piola
  //! stress; it is called from several host threads at once (voxels of different rows).
  template <class StressFn>
  parallel::ExactSum internal_forces(const StressFn& stress, const double* x, double* f);

 private:
  //! Evaluates A delta row by row and hands each run of owned nodes to
  //! emit(first node, node count, values (3 per node)): runs of interior nodes in one call,
  //! other nodes one at a time (0 for held or empty nodes). Rows go to the host threads, so
  //! emit is called concurrently (for different nodes).
  template <class Emit>
  void operator_rows(double k, double inv_dt2, const double* delta, Emit&& emit) const;
  std::size_t cell_index(long ci, long cj, long ck) const { return cells().index(ci, cj, ck); }

  const parallel::NodeGrid& grid_;
  Vec3d origin_;
  Vec3d spacing_;
  double h_;                       // the largest edge
  bool cubic_;                     // every edge equal
  double lap_[8][8];               // the cell's Laplacian over lap_scale_
  double lap_scale_;               // h for cubes (lap_ is the unit-cube Laplacian), 1 otherwise
  std::vector<std::uint8_t> occ_;  // on adjacent cells
  std::vector<std::uint8_t> adj_;  // per ghosted node: bit of each solid neighbour cell
  std::vector<double> mass_;       // per ghosted node
  std::vector<std::uint8_t> free_, fixed_;
  std::vector<double> cell_forces_;  // 24 per adjacent cell
  long global_solid_ = 0, global_free_ = 0;
  std::array<double, 27> interior_stencil_{};  // unit-cube coefficients, x fastest
  std::array<double, 4> stencil_class_{};      // mean coefficient: centre, face, edge, corner
  std::array<double, 8>
      stencil_axes_{};        // unequal edges: centre, fx, fy, fz, exy, exz, eyz, corner
  double interior_mass_ = 0;  // lumped mass of a node with 8 solid voxels of slot 0
  std::size_t slots_ = 1;     // material slots
  std::array<long, 27> interior_offset_{};  // ghosted linear offsets of the 27 neighbours
  std::array<long, 8> corner_offset_{};     // ghosted linear offset of corner m from the cell base
};

//! A stress callback per material slot: internal_forces calls slots[s] in the voxels of slot s.
template <class StressFn>
struct PerSlot {
  std::vector<StressFn> slots;
};
template <class T>
struct IsPerSlot : std::false_type {};
template <class T>
struct IsPerSlot<PerSlot<T>> : std::true_type {};

template <class StressFn>
parallel::ExactSum VoxelSystem::internal_forces(const StressFn& stress, const double* x,
                                                double* f) {
  const Box& C = cells();
  const Box& G = ghosted();
  const Box& oc = grid_.owned_cells();
  const double inv_h[3] = {1.0 / spacing_[0], 1.0 / spacing_[1], 1.0 / spacing_[2]};
  const double w = spacing_[0] * spacing_[1] * spacing_[2] / 8.0;
  const double scale[3] = {w * inv_h[0], w * inv_h[1], w * inv_h[2]};
  parallel::ExactSum energy;
  // Written for every solid voxel and read only for those (empty voxels are never read).
  cell_forces_.resize(24 * C.size());
  // One pass per voxel: the eight deformation gradients, the stresses, the node forces.
  reduce_box_rows(C, 1, &energy, [&](long cj, long ck, parallel::ExactSum* e) {
    for (long ci = C.start[0]; ci < C.start[0] + C.count[0]; ++ci) {
      const std::size_t c = C.index(ci, cj, ck);
      if (!occ_[c]) continue;
      const std::size_t base = G.index(ci, cj, ck);
      double xe[8][3], F[8][9], P[8][9], fe[8][3];
      for (int m = 0; m < 8; ++m)
        for (int a = 0; a < 3; ++a) xe[m][a] = x[3 * (base + corner_offset_[m]) + a];
      HexGauss::gradients(xe, inv_h, F);
      const auto cell = [&](const auto& fn) {
        using Fn = std::decay_t<decltype(fn)>;
        double psi = 0;
        if constexpr (std::is_invocable_r_v<double, const Fn&, const double*, double*, int>) {
          // Batched material (NeuralMTL): all eight quadrature points in one call.
          psi = fn(&F[0][0], &P[0][0], 8);
        } else {
          for (int q = 0; q < 8; ++q) psi += fn(F[q], P[q]);
        }
        return psi;
      };
      double psi = 0;
      if constexpr (IsPerSlot<StressFn>::value)
        psi = cell(stress.slots[occ_[c] - 1u]);
      else
        psi = cell(stress);
      HexGauss::forces(P, scale, fe);
      if (oc.contains(ci, cj, ck)) e[0].add(w * psi);
      double* dst = &cell_forces_[24 * c];
      for (int m = 0; m < 8; ++m)
        for (int a = 0; a < 3; ++a) dst[3 * m + a] = fe[m][a];
    }
  });
  parallel_owned(owned(), G, [&](std::size_t n, long i, long j, long k) {
    double acc[3] = {0, 0, 0};
    if (free_[n]) {
      for (int cell = 0; cell < 8; ++cell) {
        if (!(adj_[n] >> cell & 1)) continue;
        const int a = cell & 1, b = (cell >> 1) & 1, cc = (cell >> 2) & 1;
        const int l = corner_in_cell(cell);
        const double* src = &cell_forces_[24 * cell_index(i - 1 + a, j - 1 + b, k - 1 + cc)];
        for (int d = 0; d < 3; ++d) acc[d] -= src[3 * l + d];
      }
    }
    for (int d = 0; d < 3; ++d) f[3 * n + d] = acc[d];
  });
  return energy;  // rank-local; callers reduce it exactly
}

}  // namespace gen4d::elastogen
