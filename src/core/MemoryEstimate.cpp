#include "core/MemoryEstimate.hpp"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include "core/Error.hpp"

namespace gen4d::memory {
namespace {

constexpr double kPi = 3.14159265358979323846;

struct Part {
  Vec3d lo{0, 0, 0}, hi{0, 0, 0};
  double volume = 0;
};

double length(const Vec3d& a, const Vec3d& b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                   (a[2] - b[2]) * (a[2] - b[2]));
}

//! Bounds and volume of an analytic part; false for parts read from files.
bool analytic_part(const GeometryConfig& g, Part& p) {
  const double r = g.radius;
  if (g.type == "box") {
    p.lo = g.lo;
    p.hi = g.hi;
    p.volume = std::max(0.0, g.hi[0] - g.lo[0]) * std::max(0.0, g.hi[1] - g.lo[1]) *
               std::max(0.0, g.hi[2] - g.lo[2]);
    return true;
  }
  if (g.type == "sphere") {
    for (int a = 0; a < 3; ++a) {
      p.lo[a] = g.center[a] - r;
      p.hi[a] = g.center[a] + r;
    }
    p.volume = 4.0 / 3.0 * kPi * r * r * r;
    return true;
  }
  if (g.type == "capsule" || g.type == "cylinder") {
    for (int a = 0; a < 3; ++a) {
      p.lo[a] = std::min(g.a[a], g.b[a]) - r;
      p.hi[a] = std::max(g.a[a], g.b[a]) + r;
    }
    p.volume =
        kPi * r * r * length(g.a, g.b) + (g.type == "capsule" ? 4.0 / 3.0 * kPi * r * r * r : 0);
    return true;
  }
  return false;
}

}  // namespace

Estimate estimate(const Config& cfg) {
  Estimate e;
  if (cfg.geometry.empty() || !(cfg.voxel_size > 0)) return e;
  Part box;
  double volume = 0;
  for (std::size_t i = 0; i < cfg.geometry.size(); ++i) {
    Part p;
    if (!analytic_part(cfg.geometry[i], p)) return e;
    for (int a = 0; a < 3; ++a) {
      box.lo[a] = i == 0 ? p.lo[a] : std::min(box.lo[a], p.lo[a]);
      box.hi[a] = i == 0 ? p.hi[a] : std::max(box.hi[a], p.hi[a]);
    }
    volume += p.volume;
  }
  const bool mpm = cfg.solver.method == "mpm";
  const Vec3d h = mpm ? Vec3d{cfg.voxel_size, cfg.voxel_size, cfg.voxel_size} : cfg.cell_edges();
  double box_cells = 1, grid = 1;
  for (int a = 0; a < 3; ++a) {
    const double cells = std::max(1.0, std::ceil((box.hi[a] - box.lo[a]) / h[a] - 1e-9));
    box_cells *= cells;
    if (!mpm) {
      grid *= cells + 2.0 * cfg.padding + 1;  // nodes, as elastogen::layout_domain
    } else if (cfg.mpm.has_box) {
      grid *= std::max(1.0, std::ceil((cfg.mpm.hi[a] - cfg.mpm.lo[a]) / h[a] - 1e-9));
    } else {
      const int pad = std::max(cfg.padding, cfg.mpm.boundary_layers + 2);
      grid *= cells + 2.0 * pad;  // as mpm::layout_grid
    }
  }
  const double solid = std::min(box_cells, std::ceil(volume / (h[0] * h[1] * h[2])));
  e.known = true;
  e.grid = grid;
  if (mpm) {
    const double per_cell = std::pow(cfg.mpm.particles_per_axis, 3);
    e.items = solid * per_cell;
    e.bytes = e.items * kMpmBytesPerParticle + grid * kMpmBytesPerCell;
    e.breakdown = fmt::format("{:.3g} particles x {:.0f} bytes + {:.3g} grid cells x {:.0f} bytes",
                              e.items, kMpmBytesPerParticle, grid, kMpmBytesPerCell);
  } else {
    e.items = solid;
    e.bytes = solid * kElastoGenBytesPerVoxel + grid * kElastoGenBytesPerNode;
    e.breakdown =
        fmt::format("{:.3g} solid voxels x {:.0f} bytes + {:.3g} grid nodes x {:.0f} bytes", solid,
                    kElastoGenBytesPerVoxel, grid, kElastoGenBytesPerNode);
  }
  return e;
}

double available_bytes() {
  std::ifstream in("/proc/meminfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("MemAvailable:", 0) != 0) continue;
    std::istringstream fields(line.substr(13));
    double kib = -1;
    if (fields >> kib) return kib * 1024.0;
  }
  const long pages = sysconf(_SC_AVPHYS_PAGES), page = sysconf(_SC_PAGESIZE);
  return pages > 0 && page > 0 ? static_cast<double>(pages) * static_cast<double>(page) : -1;
}

std::string format_bytes(double bytes) {
  const double gib = bytes / (1024.0 * 1024.0 * 1024.0);
  if (gib >= 1) return fmt::format("{:.1f} GiB", gib);
  return fmt::format("{:.0f} MiB", bytes / (1024.0 * 1024.0));
}

void check(MPI_Comm comm, const Config& cfg) {
  const Estimate e = estimate(cfg);
  int known = e.known ? 1 : 0;
  MPI_Bcast(&known, 1, MPI_INT, 0, comm);
  if (!known) return;
  int size = 1;
  MPI_Comm_size(comm, &size);
  MPI_Comm node;
  MPI_Comm_split_type(comm, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node);
  int on_node = 1;
  MPI_Comm_size(node, &on_node);
  MPI_Comm_free(&node);
  // Every rank holds about its share of the items and the grid, plus its fixed part.
  const double need = on_node * (e.bytes / size + kBytesPerRank);
  const double have = available_bytes();
  // The node that lacks the most, as seen by all: the largest need / have.
  const double ratio = have > 0 ? need / have : 0;
  double worst = 0;
  MPI_Allreduce(&ratio, &worst, 1, MPI_DOUBLE, MPI_MAX, comm);
  if (!(worst > 1)) return;
  const std::string key = cfg.solver.method == "mpm"
                              ? "domain.voxel_size (or mpm.particles_per_axis)"
                              : "domain.voxel_size";
  throw RuntimeError(fmt::format(
      "{}: the run needs about {} ({}, plus {} per rank; {} rank(s) on a node), a node of "
      "this run has {} available (MemAvailable); use a larger {} or more nodes, or pass "
      "--skip-memory-check",
      cfg.source, format_bytes(need), e.breakdown, format_bytes(kBytesPerRank), on_node,
      format_bytes(need / worst), key));
}

}  // namespace gen4d::memory
