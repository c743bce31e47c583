#include "elastogen/SurfaceEmbedding.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <limits>

#include "core/Error.hpp"
#include "io/GridBox.hpp"
#include "parallel/Comm.hpp"

namespace gen4d::elastogen {

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
  rank_ = parallel::rank(comm_);
  size_ = parallel::size(comm_);
  std::vector<PointAnchor> anchors =
      source_ == SurfaceSource::Mesh ? build_mesh(shape) : build_voxels(shape);
  points_ = std::make_unique<PointEmbedding>(sys_, std::move(anchors), vertex_count_,
                                             source_ == SurfaceSource::Mesh, "surface embedding");
}

std::vector<PointAnchor> SurfaceEmbedding::build_mesh(const geometry::Shape& shape) {
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

  PointPlacer placer(sys_, shape);
  long offset = 0;
  for (const auto* part : parts) {
    const geometry::Mesh& mesh = part->mesh();
    if (rank_ == 0)
      for (const auto& t : mesh.triangles)
        triangles_.push_back({static_cast<std::int32_t>(t[0] + offset),
                              static_cast<std::int32_t>(t[1] + offset),
                              static_cast<std::int32_t>(t[2] + offset)});
    for (std::size_t v = 0; v < mesh.vertices.size(); ++v)
      placer.add(offset + static_cast<long>(v), mesh.vertices[v].data());
    offset += static_cast<long>(mesh.vertices.size());
  }
  long extrapolated = placer.extrapolated();
  double worst = placer.max_extrapolation();
  extrapolated_ = parallel::sum_of(comm_, static_cast<long long>(extrapolated));
  max_extrapolation_ = parallel::max_of(comm_, worst);
  return placer.take();
}

std::vector<PointAnchor> SurfaceEmbedding::build_voxels(const geometry::Shape& shape) {
  VoxelProbe probe(sys_, shape);
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
  std::vector<long> all = parallel::gather(comm_, keys);

  // Rank 0: quads in a fixed order (voxels x fastest, then axis and side), vertices numbered
  // by ascending global node index, each anchored at its node (PointEmbedding sends it to the
  // rank owning the node).
  std::vector<PointAnchor> anchors;
  long header[2] = {0, 0};
  if (rank_ == 0) {
    std::sort(all.begin(), all.end());
    std::vector<std::array<long, 4>> quads;
    quads.reserve(all.size());
    for (long key : all) {
      const long cell = key / 6, a = (key % 6) / 2, side = key % 2;
      const std::array<long, 3> c{cell % cells[0], (cell / cells[0]) % cells[1],
                                  cell / (cells[0] * cells[1])};
      const std::array<long, 4> quad =
          io::cell_face_nodes(c, static_cast<int>(a), static_cast<int>(side), nodes);
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
    for (std::size_t id = 0; id < verts.size(); ++id) {
      const long nd = verts[id];
      anchors.push_back({static_cast<long>(id),
                         {nd % nodes[0], (nd / nodes[0]) % nodes[1], nd / (nodes[0] * nodes[1])},
                         {0.0, 0.0, 0.0}});
    }
    header[0] = static_cast<long>(verts.size());
    header[1] = static_cast<long>(triangles_.size());
  }
  parallel::broadcast(comm_, header, 2);
  vertex_count_ = header[0];
  triangle_count_ = header[1];
  return anchors;
}

}  // namespace gen4d::elastogen
