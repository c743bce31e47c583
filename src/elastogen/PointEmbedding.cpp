#include "elastogen/PointEmbedding.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

#include "core/Error.hpp"
#include "parallel/Distribute.hpp"
#include "parallel/Comm.hpp"

namespace gen4d::elastogen {

namespace {

//! Squared distance, in voxel units, from grid-space point u to the box of voxel c.
double distance2(const std::array<double, 3>& u, const std::array<long, 3>& c) {
  double d2 = 0;
  for (int a = 0; a < 3; ++a) {
    const double lo = static_cast<double>(c[a]);
    const double d = std::max({lo - u[a], 0.0, u[a] - (lo + 1.0)});
    d2 += d * d;
  }
  return d2;
}

//! The solid voxel nearest to u (ties: lower linear index), searching cubes of growing radius
//! around c0 until no voxel outside the cube can be nearer.
std::array<long, 3> nearest_solid(VoxelProbe& probe, const std::array<double, 3>& u,
                                  const std::array<long, 3>& c0) {
  const double e = std::sqrt(distance2(u, c0));  // > 0 only when u lies outside the grid
  const auto& n = probe.cells();
  bool found = false;
  double best_d2 = 0;
  long best_key = 0;
  std::array<long, 3> best{};
  for (long r = 1;; r *= 2) {
    std::array<long, 3> lo{}, hi{};
    bool whole = true;
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::max(0L, c0[a] - r);
      hi[a] = std::min(n[a] - 1, c0[a] + r);
      whole = whole && lo[a] == 0 && hi[a] == n[a] - 1;
    }
    for (long k = lo[2]; k <= hi[2]; ++k)
      for (long j = lo[1]; j <= hi[1]; ++j)
        for (long i = lo[0]; i <= hi[0]; ++i) {
          const std::array<long, 3> c{i, j, k};
          if (!probe.solid(c)) continue;
          const double d2 = distance2(u, c);
          const long key = probe.linear(c);
          if (!found || d2 < best_d2 || (d2 == best_d2 && key < best_key)) {
            found = true;
            best_d2 = d2;
            best_key = key;
            best = c;
          }
        }
    const double reach = static_cast<double>(r) - e;  // any voxel outside is at least this far
    if (found && (whole || (reach > 0 && best_d2 < reach * reach))) return best;
    if (whole) throw RuntimeError("point embedding: the grid holds no solid voxel");
  }
}

std::array<double, 8> corner_weights(const std::array<double, 3>& t) {
  std::array<double, 8> w{};
  for (int m = 0; m < 8; ++m)
    w[m] = ((m & 1) ? t[0] : 1.0 - t[0]) * ((m & 2) ? t[1] : 1.0 - t[1]) *
           ((m & 4) ? t[2] : 1.0 - t[2]);
  return w;
}

//! d w_m / d t_a of the trilinear weights at t.
std::array<std::array<double, 3>, 8> corner_weight_gradients(const std::array<double, 3>& t) {
  std::array<std::array<double, 3>, 8> g{};
  for (int m = 0; m < 8; ++m) {
    double f[3], df[3];
    for (int a = 0; a < 3; ++a) {
      const bool upper = (m >> a) & 1;
      f[a] = upper ? t[a] : 1.0 - t[a];
      df[a] = upper ? 1.0 : -1.0;
    }
    g[m] = {df[0] * f[1] * f[2], f[0] * df[1] * f[2], f[0] * f[1] * df[2]};
  }
  return g;
}

}  // namespace

VoxelProbe::VoxelProbe(const VoxelSystem& sys, const geometry::Shape& shape)
    : sys_(sys), shape_(shape), cells_(sys.grid().global_cells()) {}

bool VoxelProbe::inside_grid(const std::array<long, 3>& c) const {
  for (int a = 0; a < 3; ++a)
    if (c[a] < 0 || c[a] >= cells_[a]) return false;
  return true;
}

bool VoxelProbe::solid(const std::array<long, 3>& c) {
  if (!inside_grid(c)) return false;
  if (sys_.cells().contains(c[0], c[1], c[2])) return sys_.solid(c[0], c[1], c[2]);
  const long key = linear(c);
  if (auto it = cache_.find(key); it != cache_.end()) return it->second != 0;
  std::vector<std::uint8_t> occ;
  const Eigen::Vector3d origin(sys_.origin()[0], sys_.origin()[1], sys_.origin()[2]);
  const Vec3d& h = sys_.spacing();
  geometry::voxelize(shape_, origin, Eigen::Vector3d(h[0], h[1], h[2]), c,
                     {c[0] + 1, c[1] + 1, c[2] + 1}, occ);
  cache_.emplace(key, occ[0]);
  return occ[0] != 0;
}

PointPlacer::PointPlacer(const VoxelSystem& sys, const geometry::Shape& shape)
    : sys_(sys), probe_(sys, shape) {}

void PointPlacer::add(long id, const double* p) {
  const auto& cells = probe_.cells();
  const Box& oc = sys_.grid().owned_cells();
  std::array<double, 3> u{};
  std::array<long, 3> c0{};
  for (int a = 0; a < 3; ++a) {
    u[a] = (p[a] - sys_.origin()[a]) / sys_.spacing()[a];
    c0[a] = std::clamp(static_cast<long>(std::floor(u[a])), 0L, cells[a] - 1);
  }
  if (!oc.contains(c0[0], c0[1], c0[2])) return;
  std::array<long, 3> c = c0;
  if (!probe_.solid(c0)) {
    c = nearest_solid(probe_, u, c0);
    ++extrapolated_;
    worst_ = std::max(worst_, std::sqrt(distance2(u, c)));
  }
  PointAnchor anchor{id, c, {}};
  for (int a = 0; a < 3; ++a) anchor.t[a] = u[a] - static_cast<double>(c[a]);
  anchors_.push_back(anchor);
}

PointEmbedding::PointEmbedding(const VoxelSystem& sys, std::vector<PointAnchor> anchors, long count,
                               bool voxel_anchors, const std::string& what)
    : comm_(sys.grid().comm()), count_(count), h_(sys.spacing()), voxel_anchors_(voxel_anchors) {
  rank_ = parallel::rank(comm_);
  size_ = parallel::size(comm_);
  const parallel::NodeGrid& grid = sys.grid();
  const Box& G = sys.ghosted();
  for (int m = 0; m < 8; ++m)
    corner_offset_[m] = static_cast<std::size_t>(
        (m & 1) + G.count[0] * (((m >> 1) & 1) + G.count[1] * ((m >> 2) & 1)));

  // Each anchor goes to the rank owning its base node (which owns the voxel above it).
  std::vector<long> id(anchors.size()), base(3 * anchors.size());
  std::vector<double> t(3 * anchors.size());
  std::vector<int> dest(anchors.size());
  for (std::size_t e = 0; e < anchors.size(); ++e) {
    const PointAnchor& a = anchors[e];
    id[e] = a.id;
    for (int d = 0; d < 3; ++d) {
      base[3 * e + d] = a.base[d];
      t[3 * e + d] = a.t[d];
    }
    dest[e] = grid.owner_of(a.base[0], a.base[1], a.base[2]);
  }
  anchors.clear();
  anchors.shrink_to_fit();
  parallel::RowExchange exchange;
  exchange.add(id, 1).add(base, 3).add(t, 3);
  exchange.exchange(comm_, dest);

  std::vector<std::size_t> order(id.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return id[a] < id[b]; });
  const std::array<long, 3> nodes = grid.global_nodes();
  ids_.reserve(order.size());
  for (std::size_t e : order) {
    const long* b = &base[3 * e];
    const long hi = voxel_anchors_ ? 1 : 0;  // the far corner must exist too
    if (!G.contains(b[0], b[1], b[2]) || !G.contains(b[0] + hi, b[1] + hi, b[2] + hi) ||
        b[0] + hi >= nodes[0] || b[1] + hi >= nodes[1] || b[2] + hi >= nodes[2])
      throw RuntimeError(fmt::format("{}: point {}'s voxel is not on its rank", what, id[e]));
    const std::array<double, 3> te{t[3 * e], t[3 * e + 1], t[3 * e + 2]};
    ids_.push_back(id[e]);
    base_.push_back(G.index(b[0], b[1], b[2]));
    weights_.push_back(corner_weights(te));
    if (voxel_anchors_) t_.push_back(te);
  }

  // Rank 0 learns which points each rank evaluates, once.
  gather_ids_ = parallel::gather(comm_, ids_);
  const long total = static_cast<long>(gather_ids_.size());
  // Every id exactly once: the count matches and the ids, sorted, are 0 .. count - 1.
  int bad = 0;
  if (rank_ == 0) {
    if (total != count_) {
      bad = 1;
    } else {
      std::vector<long> sorted = gather_ids_;
      std::sort(sorted.begin(), sorted.end());
      for (long e = 0; e < total && !bad; ++e) bad = sorted[e] != e;
    }
  }
  parallel::broadcast(comm_, &bad, 1);
  if (bad)
    throw RuntimeError(
        fmt::format("{}: {} anchors placed for {} points, not one per point", what, total, count_));
}

void PointEmbedding::evaluate(const double* x, std::vector<double>& out) const {
  out.assign(3 * ids_.size(), 0.0);
  for (std::size_t v = 0; v < ids_.size(); ++v) {
    double acc[3] = {0, 0, 0};
    const std::array<double, 8>& w = weights_[v];
    for (int m = 0; m < 8; ++m) {
      if (w[m] == 0.0) continue;
      const double* xm = x + 3 * (base_[v] + corner_offset_[m]);
      for (int d = 0; d < 3; ++d) acc[d] += w[m] * xm[d];
    }
    for (int d = 0; d < 3; ++d) out[3 * v + d] = acc[d];
  }
}

void PointEmbedding::evaluate_gradients(const double* x, std::vector<double>& out) const {
  if (!voxel_anchors_)
    throw std::logic_error("PointEmbedding: gradients need points anchored in voxels");
  out.assign(9 * ids_.size(), 0.0);
  const double inv_h[3] = {1.0 / h_[0], 1.0 / h_[1], 1.0 / h_[2]};
  for (std::size_t v = 0; v < ids_.size(); ++v) {
    const auto g = corner_weight_gradients(t_[v]);
    const double* x0 = x + 3 * base_[v];
    double F[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
    // The weight gradients sum to zero, so differences to corner 0 give the same map with
    // less cancellation.
    for (int m = 1; m < 8; ++m) {
      const double* xm = x + 3 * (base_[v] + corner_offset_[m]);
      for (int d = 0; d < 3; ++d) {
        const double dx = xm[d] - x0[d];
        for (int a = 0; a < 3; ++a) F[3 * d + a] += dx * g[m][a];
      }
    }
    for (int e = 0; e < 9; ++e) out[9 * v + e] = F[e] * inv_h[e % 3];
  }
}

std::vector<double> PointEmbedding::gather(const std::vector<double>& local, int width) const {
  if (local.size() != static_cast<std::size_t>(width) * ids_.size())
    throw std::logic_error("PointEmbedding::gather: array size does not match the local points");
  // In rank order, as gather_ids_.
  const std::vector<double> packed = parallel::gather(comm_, local);
  if (rank_ != 0) return {};
  std::vector<double> out(static_cast<std::size_t>(width) * static_cast<std::size_t>(count_));
  for (std::size_t e = 0; e < gather_ids_.size(); ++e)
    for (int d = 0; d < width; ++d)
      out[static_cast<std::size_t>(width) * gather_ids_[e] + d] = packed[width * e + d];
  return out;
}

std::vector<double> PointEmbedding::gather(const double* x) const {
  std::vector<double> local;
  evaluate(x, local);
  return gather(local, 3);
}

}  // namespace gen4d::elastogen
