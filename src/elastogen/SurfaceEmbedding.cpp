#include "elastogen/SurfaceEmbedding.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "core/Error.hpp"
#include "parallel/PetscCheck.hpp"

namespace gen4d::elastogen {

namespace {

//! Solid state of any voxel of the grid: this rank's voxelization where it has one, else the
//! same centre test on demand (voxelize() decides each voxel from its global index alone, so
//! both agree on every rank).
class OccupancyProbe {
 public:
  OccupancyProbe(const VoxelSystem& sys, const geometry::Shape& shape)
      : sys_(sys), shape_(shape), cells_(sys.grid().global_cells()) {}

  bool inside_grid(const std::array<long, 3>& c) const {
    for (int a = 0; a < 3; ++a)
      if (c[a] < 0 || c[a] >= cells_[a]) return false;
    return true;
  }
  bool solid(const std::array<long, 3>& c) {
    if (!inside_grid(c)) return false;
    if (sys_.cells().contains(c[0], c[1], c[2])) return sys_.solid(c[0], c[1], c[2]);
    const long key = linear(c);
    if (auto it = cache_.find(key); it != cache_.end()) return it->second != 0;
    std::vector<std::uint8_t> occ;
    const Eigen::Vector3d origin(sys_.origin()[0], sys_.origin()[1], sys_.origin()[2]);
    geometry::voxelize(shape_, origin, sys_.h(), c, {c[0] + 1, c[1] + 1, c[2] + 1}, occ);
    cache_.emplace(key, occ[0]);
    return occ[0] != 0;
  }
  long linear(const std::array<long, 3>& c) const {
    return (c[2] * cells_[1] + c[1]) * cells_[0] + c[0];
  }
  const std::array<long, 3>& cells() const { return cells_; }

 private:
  const VoxelSystem& sys_;
  const geometry::Shape& shape_;
  std::array<long, 3> cells_;
  std::unordered_map<long, std::uint8_t> cache_;
};

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
std::array<long, 3> nearest_solid(OccupancyProbe& probe, const std::array<double, 3>& u,
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
    if (whole) throw RuntimeError("surface embedding: the grid holds no solid voxel");
  }
}

std::array<double, 8> corner_weights(const std::array<double, 3>& t) {
  std::array<double, 8> w{};
  for (int m = 0; m < 8; ++m)
    w[m] = ((m & 1) ? t[0] : 1.0 - t[0]) * ((m & 2) ? t[1] : 1.0 - t[1]) *
           ((m & 4) ? t[2] : 1.0 - t[2]);
  return w;
}

}  // namespace

SurfaceSource choose_surface_source(const Config& cfg) {
  if (cfg.output.surface_source == "voxels") return SurfaceSource::Voxels;
  if (cfg.output.surface_source == "mesh") return SurfaceSource::Mesh;
  const bool all_meshes = !cfg.geometry.empty() &&
                          std::all_of(cfg.geometry.begin(), cfg.geometry.end(),
                                      [](const GeometryConfig& g) { return g.type == "mesh"; });
  return all_meshes ? SurfaceSource::Mesh : SurfaceSource::Voxels;
}

SurfaceEmbedding::SurfaceEmbedding(const VoxelSystem& sys, const geometry::Shape& shape,
                                   SurfaceSource source)
    : sys_(sys), comm_(sys.grid().comm()), source_(source) {
  MPI_Comm_rank(comm_, &rank_);
  MPI_Comm_size(comm_, &size_);
  const Box& G = sys_.ghosted();
  for (int m = 0; m < 8; ++m)
    corner_offset_[m] = static_cast<std::size_t>(
        (m & 1) + G.count[0] * (((m >> 1) & 1) + G.count[1] * ((m >> 2) & 1)));
  // Process grid of the DMDA (ranks numbered x fastest) and each process's node range.
  PetscInt m = 1, n = 1, p = 1;
  const PetscInt *lx = nullptr, *ly = nullptr, *lz = nullptr;
  DM dm = sys_.grid().dm(3);
  parallel::check(DMDAGetInfo(dm, nullptr, nullptr, nullptr, nullptr, &m, &n, &p, nullptr, nullptr,
                              nullptr, nullptr, nullptr, nullptr),
                  "DMDAGetInfo");
  parallel::check(DMDAGetOwnershipRanges(dm, &lx, &ly, &lz), "DMDAGetOwnershipRanges");
  procs_ = {m, n, p};
  const PetscInt* ranges[3] = {lx, ly, lz};
  for (int a = 0; a < 3; ++a) {
    long end = 0;
    for (long q = 0; q < procs_[a]; ++q) owner_ends_[a].push_back(end += ranges[a][q]);
  }
  const Box& O = sys_.owned();
  if (O.size() > 0 && owner_of_node(O.start) != rank_)
    throw RuntimeError("surface embedding: unexpected DMDA process numbering");

  if (source_ == SurfaceSource::Mesh)
    build_mesh(shape);
  else
    build_voxels(shape);

  // Rank 0 learns which vertices each rank evaluates, once.
  const int local = static_cast<int>(ids_.size());
  std::vector<int> counts(rank_ == 0 ? size_ : 0), displs(rank_ == 0 ? size_ : 0);
  MPI_Gather(&local, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, comm_);
  long total = 0;
  for (int r = 0; r < static_cast<int>(counts.size()); ++r) {
    displs[r] = static_cast<int>(total);
    total += counts[r];
  }
  if (rank_ == 0) gather_ids_.resize(total);
  MPI_Gatherv(ids_.data(), local, MPI_LONG, gather_ids_.data(), counts.data(), displs.data(),
              MPI_LONG, 0, comm_);
  if (rank_ == 0) {
    if (total != vertex_count_)
      throw RuntimeError(
          fmt::format("surface embedding: {} of {} vertices placed", total, vertex_count_));
    gather_counts_.resize(size_);
    gather_displs_.resize(size_);
    for (int r = 0; r < size_; ++r) {
      gather_counts_[r] = 3 * counts[r];
      gather_displs_[r] = 3 * displs[r];
    }
  }
}

int SurfaceEmbedding::owner_of_node(const std::array<long, 3>& node) const {
  long q[3];
  for (int a = 0; a < 3; ++a) {
    const auto& ends = owner_ends_[a];
    q[a] = std::upper_bound(ends.begin(), ends.end(), node[a]) - ends.begin();
    q[a] = std::min<long>(q[a], procs_[a] - 1);
  }
  return static_cast<int>(q[0] + procs_[0] * (q[1] + procs_[1] * q[2]));
}

void SurfaceEmbedding::build_mesh(const geometry::Shape& shape) {
  std::vector<const geometry::TriangleMesh*> parts;
  if (const auto* u = dynamic_cast<const geometry::Union*>(&shape)) {
    for (std::size_t i = 0; i < u->size(); ++i)
      parts.push_back(dynamic_cast<const geometry::TriangleMesh*>(&u->part(i)));
  } else {
    parts.push_back(dynamic_cast<const geometry::TriangleMesh*>(&shape));
  }
  long vertices = 0, triangles = 0;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    if (parts[i] == nullptr)
      throw InputError(fmt::format(
          "output.surface_source: [[geometry]] #{} is not a mesh; a mesh surface needs every "
          "part to be a mesh (use \"voxels\" or \"auto\")",
          i + 1));
    vertices += static_cast<long>(parts[i]->mesh().vertices.size());
    triangles += static_cast<long>(parts[i]->mesh().triangles.size());
  }
  if (vertices > std::numeric_limits<std::int32_t>::max())
    throw RuntimeError(fmt::format("surface: {} mesh vertices exceed 2^31 - 1", vertices));
  vertex_count_ = vertices;
  triangle_count_ = triangles;

  OccupancyProbe probe(sys_, shape);
  const auto& cells = probe.cells();
  const Box& oc = sys_.grid().owned_cells();
  const double h = sys_.h();
  std::vector<Anchor> anchors;
  long offset = 0, extrapolated = 0;
  double worst = 0;
  for (const auto* part : parts) {
    const geometry::Mesh& mesh = part->mesh();
    if (rank_ == 0)
      for (const auto& t : mesh.triangles)
        triangles_.push_back({static_cast<std::int32_t>(t[0] + offset),
                              static_cast<std::int32_t>(t[1] + offset),
                              static_cast<std::int32_t>(t[2] + offset)});
    for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
      std::array<double, 3> u{};
      std::array<long, 3> c0{};
      for (int a = 0; a < 3; ++a) {
        u[a] = (mesh.vertices[v][a] - sys_.origin()[a]) / h;
        c0[a] = std::clamp(static_cast<long>(std::floor(u[a])), 0L, cells[a] - 1);
      }
      if (!oc.contains(c0[0], c0[1], c0[2])) continue;
      std::array<long, 3> c = c0;
      if (!probe.solid(c0)) {
        c = nearest_solid(probe, u, c0);
        ++extrapolated;
        worst = std::max(worst, std::sqrt(distance2(u, c)));
      }
      Anchor anchor{offset + static_cast<long>(v), c, {}};
      for (int a = 0; a < 3; ++a) anchor.t[a] = u[a] - static_cast<double>(c[a]);
      anchors.push_back(anchor);
    }
    offset += static_cast<long>(mesh.vertices.size());
  }
  MPI_Allreduce(&extrapolated, &extrapolated_, 1, MPI_LONG, MPI_SUM, comm_);
  MPI_Allreduce(&worst, &max_extrapolation_, 1, MPI_DOUBLE, MPI_MAX, comm_);
  distribute(std::move(anchors));
}

void SurfaceEmbedding::build_voxels(const geometry::Shape& shape) {
  OccupancyProbe probe(sys_, shape);
  const auto& cells = probe.cells();
  const auto& nodes = sys_.grid().global_nodes();
  const Box& oc = sys_.grid().owned_cells();
  // Face keys: 6 * (global linear index of the solid voxel) + 2 * axis + side.
  std::vector<long> keys;
  for (long k = oc.start[2]; k < oc.start[2] + oc.count[2]; ++k)
    for (long j = oc.start[1]; j < oc.start[1] + oc.count[1]; ++j)
      for (long i = oc.start[0]; i < oc.start[0] + oc.count[0]; ++i) {
        const std::array<long, 3> c{i, j, k};
        if (!probe.solid(c)) continue;
        for (int a = 0; a < 3; ++a)
          for (int side = 0; side < 2; ++side) {
            std::array<long, 3> nb = c;
            nb[a] += side ? 1 : -1;
            if (!probe.solid(nb)) keys.push_back(6 * probe.linear(c) + 2 * a + side);
          }
      }
  const int local = static_cast<int>(keys.size());
  std::vector<int> counts(rank_ == 0 ? size_ : 0), displs(rank_ == 0 ? size_ : 0);
  MPI_Gather(&local, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, comm_);
  long total = 0;
  for (int r = 0; r < static_cast<int>(counts.size()); ++r) {
    displs[r] = static_cast<int>(total);
    total += counts[r];
  }
  std::vector<long> all(rank_ == 0 ? total : 0);
  MPI_Gatherv(keys.data(), local, MPI_LONG, all.data(), counts.data(), displs.data(), MPI_LONG, 0,
              comm_);

  // Rank 0: quads in a fixed order (voxels x fastest, then axis and side), vertices numbered
  // by ascending global node index, and each vertex sent to the rank owning its node.
  std::vector<int> send_counts(rank_ == 0 ? size_ : 0), send_displs(rank_ == 0 ? size_ : 0);
  std::vector<long> send;  // (vertex id, node linear index) pairs, grouped by owner
  long header[2] = {0, 0};
  if (rank_ == 0) {
    std::sort(all.begin(), all.end());
    auto node_id = [&](const std::array<long, 3>& q) {
      return (q[2] * nodes[1] + q[1]) * nodes[0] + q[0];
    };
    const long corner[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    std::vector<std::array<long, 4>> quads;
    quads.reserve(all.size());
    for (long key : all) {
      const long cell = key / 6, a = (key % 6) / 2, side = key % 2;
      const std::array<long, 3> c{cell % cells[0], (cell / cells[0]) % cells[1],
                                  cell / (cells[0] * cells[1])};
      const long b = (a + 1) % 3, cc = (a + 2) % 3;  // b x cc = a: this order faces +a
      std::array<long, 4> quad{};
      for (int q = 0; q < 4; ++q) {
        std::array<long, 3> nd = c;
        nd[a] += side;
        nd[b] += corner[q][0];
        nd[cc] += corner[q][1];
        quad[side ? q : 3 - q] = node_id(nd);
      }
      quads.push_back(quad);
    }
    std::vector<long> verts;
    verts.reserve(4 * quads.size());
    for (const auto& q : quads) verts.insert(verts.end(), q.begin(), q.end());
    std::sort(verts.begin(), verts.end());
    verts.erase(std::unique(verts.begin(), verts.end()), verts.end());
    if (static_cast<long>(verts.size()) > std::numeric_limits<std::int32_t>::max())
      throw RuntimeError("surface: more than 2^31 - 1 boundary nodes");
    auto vid = [&](long node) {
      return static_cast<std::int32_t>(std::lower_bound(verts.begin(), verts.end(), node) -
                                       verts.begin());
    };
    for (const auto& q : quads) {
      const std::array<std::int32_t, 4> v{vid(q[0]), vid(q[1]), vid(q[2]), vid(q[3])};
      triangles_.push_back({v[0], v[1], v[2]});
      triangles_.push_back({v[0], v[2], v[3]});
    }
    std::vector<std::vector<long>> per_rank(size_);
    for (std::size_t id = 0; id < verts.size(); ++id) {
      const long nd = verts[id];
      const std::array<long, 3> q{nd % nodes[0], (nd / nodes[0]) % nodes[1],
                                  nd / (nodes[0] * nodes[1])};
      auto& out = per_rank[owner_of_node(q)];
      out.push_back(static_cast<long>(id));
      out.push_back(nd);
    }
    for (int r = 0; r < size_; ++r) {
      send_displs[r] = static_cast<int>(send.size());
      send_counts[r] = static_cast<int>(per_rank[r].size());
      send.insert(send.end(), per_rank[r].begin(), per_rank[r].end());
    }
    header[0] = static_cast<long>(verts.size());
    header[1] = static_cast<long>(triangles_.size());
  }
  MPI_Bcast(header, 2, MPI_LONG, 0, comm_);
  vertex_count_ = header[0];
  triangle_count_ = header[1];
  int mine = 0;
  MPI_Scatter(send_counts.data(), 1, MPI_INT, &mine, 1, MPI_INT, 0, comm_);
  std::vector<long> received(mine);
  MPI_Scatterv(send.data(), send_counts.data(), send_displs.data(), MPI_LONG, received.data(), mine,
               MPI_LONG, 0, comm_);
  std::vector<Anchor> anchors;
  for (int e = 0; e + 1 < mine; e += 2) {
    const long nd = received[e + 1];
    anchors.push_back({received[e],
                       {nd % nodes[0], (nd / nodes[0]) % nodes[1], nd / (nodes[0] * nodes[1])},
                       {0.0, 0.0, 0.0}});
  }
  finish(std::move(anchors));
}

void SurfaceEmbedding::distribute(std::vector<Anchor> anchors) {
  const Box& oc = sys_.grid().owned_cells();
  std::vector<Anchor> keep;
  std::vector<std::vector<Anchor>> away(size_);
  for (const Anchor& a : anchors) {
    if (oc.contains(a.base[0], a.base[1], a.base[2]))
      keep.push_back(a);
    else
      away[owner_of_node(a.base)].push_back(a);
  }
  // Exchange (id, cell) as longs and t as doubles.
  std::vector<int> send_counts(size_), recv_counts(size_);
  for (int r = 0; r < size_; ++r) send_counts[r] = static_cast<int>(away[r].size());
  MPI_Alltoall(send_counts.data(), 1, MPI_INT, recv_counts.data(), 1, MPI_INT, comm_);
  std::vector<int> sl(size_), sd(size_), rl(size_), rd(size_), sdd(size_), rdd(size_), sc3(size_),
      rc3(size_);
  std::vector<long> send_l;
  std::vector<double> send_d;
  int recv_total = 0;
  for (int r = 0; r < size_; ++r) {
    sd[r] = static_cast<int>(send_l.size());
    sdd[r] = static_cast<int>(send_d.size());
    for (const Anchor& a : away[r]) {
      send_l.insert(send_l.end(), {a.id, a.base[0], a.base[1], a.base[2]});
      send_d.insert(send_d.end(), a.t.begin(), a.t.end());
    }
    sl[r] = 4 * send_counts[r];
    sc3[r] = 3 * send_counts[r];
    rl[r] = 4 * recv_counts[r];
    rc3[r] = 3 * recv_counts[r];
    rd[r] = 4 * recv_total;
    rdd[r] = 3 * recv_total;
    recv_total += recv_counts[r];
  }
  std::vector<long> recv_l(4 * static_cast<std::size_t>(recv_total));
  std::vector<double> recv_d(3 * static_cast<std::size_t>(recv_total));
  MPI_Alltoallv(send_l.data(), sl.data(), sd.data(), MPI_LONG, recv_l.data(), rl.data(), rd.data(),
                MPI_LONG, comm_);
  MPI_Alltoallv(send_d.data(), sc3.data(), sdd.data(), MPI_DOUBLE, recv_d.data(), rc3.data(),
                rdd.data(), MPI_DOUBLE, comm_);
  for (int e = 0; e < recv_total; ++e)
    keep.push_back({recv_l[4 * e],
                    {recv_l[4 * e + 1], recv_l[4 * e + 2], recv_l[4 * e + 3]},
                    {recv_d[3 * e], recv_d[3 * e + 1], recv_d[3 * e + 2]}});
  finish(std::move(keep));
}

void SurfaceEmbedding::finish(std::vector<Anchor> anchors) {
  std::sort(anchors.begin(), anchors.end(),
            [](const Anchor& a, const Anchor& b) { return a.id < b.id; });
  const Box& G = sys_.ghosted();
  for (const Anchor& a : anchors) {
    if (!G.contains(a.base[0], a.base[1], a.base[2]))
      throw RuntimeError("surface embedding: a vertex's voxel is not on its rank");
    ids_.push_back(a.id);
    base_.push_back(G.index(a.base[0], a.base[1], a.base[2]));
    weights_.push_back(corner_weights(a.t));
  }
}

void SurfaceEmbedding::evaluate(const double* x, std::vector<double>& out) const {
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

std::vector<double> SurfaceEmbedding::gather(const double* x) const {
  std::vector<double> local;
  evaluate(x, local);
  std::vector<double> packed(rank_ == 0 ? 3 * gather_ids_.size() : 0);
  MPI_Gatherv(local.data(), static_cast<int>(local.size()), MPI_DOUBLE, packed.data(),
              gather_counts_.data(), gather_displs_.data(), MPI_DOUBLE, 0, comm_);
  if (rank_ != 0) return {};
  std::vector<double> out(3 * static_cast<std::size_t>(vertex_count_));
  for (std::size_t e = 0; e < gather_ids_.size(); ++e)
    for (int d = 0; d < 3; ++d) out[3 * gather_ids_[e] + d] = packed[3 * e + d];
  return out;
}

}  // namespace gen4d::elastogen
