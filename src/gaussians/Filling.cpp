#include "gaussians/Filling.hpp"

#include <Eigen/Dense>
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>

#include "core/Error.hpp"
#include "core/Log.hpp"

namespace gen4d::gaussians {

namespace {

using Clock = std::chrono::steady_clock;
constexpr double kPi = 3.14159265358979323846;

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

//! Prints a progress line when `interval` seconds have passed since the last one.
class Ticker {
 public:
  explicit Ticker(double interval) : interval_(interval) {}
  void tick(const char* stage, std::size_t done, std::size_t total) {
    if ((done & 4095) != 0 || seconds_since(last_) < interval_) return;
    last_ = Clock::now();
    log::info("particle filling: {} {}/{} ({:.0f} s)", stage, done, total, seconds_since(start_));
  }

 private:
  double interval_;
  Clock::time_point start_ = Clock::now();
  Clock::time_point last_ = Clock::now();
};

[[noreturn]] void bad_option(const std::string& what) {
  throw InputError("particle filling: " + what);
}

void check_options(const FillingOptions& o) {
  if (o.n_grid < 2 || o.n_grid > 1024)
    bad_option(fmt::format("n_grid = {} is outside 2..1024", o.n_grid));
  if (!std::isfinite(o.density_threshold)) bad_option("density_threshold is not a finite number");
  if (!std::isfinite(o.search_threshold)) bad_option("search_threshold is not a finite number");
  if (o.max_particles_per_cell < 1 || o.max_particles_per_cell > 1000)
    bad_option(
        fmt::format("max_particles_per_cell = {} is outside 1..1000", o.max_particles_per_cell));
  if (o.search_exclude_direction < -1 || o.search_exclude_direction > 5)
    bad_option(
        fmt::format("search_exclude_direction = {} is outside -1..5", o.search_exclude_direction));
  if (o.ray_cast_direction < -1 || o.ray_cast_direction > 5)
    bad_option(fmt::format("ray_cast_direction = {} is outside -1..5", o.ray_cast_direction));
  if (!(o.support_sigmas > 0) || !std::isfinite(o.support_sigmas))
    bad_option("support_sigmas must be a positive number");
  if (o.max_support_cells < 1 || o.max_support_cells > 64)
    bad_option(fmt::format("max_support_cells = {} is outside 1..64", o.max_support_cells));
  if (o.box_padding_cells < 0 || o.box_padding_cells > 64)
    bad_option(fmt::format("box_padding_cells = {} is outside 0..64", o.box_padding_cells));
  if (o.has_box)
    for (int a = 0; a < 3; ++a)
      if (!std::isfinite(o.box_lo[a]) || !std::isfinite(o.box_hi[a]) ||
          !(o.box_hi[a] > o.box_lo[a]))
        bad_option(fmt::format("box axis {}: [{}, {}] is not a finite interval of positive length",
                               "xyz"[a], o.box_lo[a], o.box_hi[a]));
}

void check_splats(const SplatSet& s) {
  s.check_sizes();
  if (s.size() == 0) bad_option("no splats to fill");
  auto finite = [](const std::vector<double>& v, std::size_t first, std::size_t n) {
    for (std::size_t k = first; k < first + n; ++k)
      if (!std::isfinite(v[k])) return false;
    return true;
  };
  const std::size_t per_sh = 3 * static_cast<std::size_t>(s.coefficients());
  for (std::size_t i = 0; i < s.size(); ++i) {
    const char* bad = !finite(s.position, 3 * i, 3)       ? "position"
                      : !finite(s.scale, 3 * i, 3)        ? "scale"
                      : !finite(s.rotation, 4 * i, 4)     ? "rotation"
                      : !finite(s.opacity, i, 1)          ? "opacity"
                      : !finite(s.sh, per_sh * i, per_sh) ? "sh"
                                                          : nullptr;
    if (bad) bad_option(fmt::format("splat {} has a non-finite {}", i, bad));
  }
}

//! SplitMix64: a counter-based hash, so a particle's position depends on (seed, cell, k) only.
std::uint64_t mix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

double unit(std::uint64_t h) {
  return static_cast<double>(h >> 11) * (1.0 / 9007199254740992.0);
}

//! k-d tree over points for nearest-neighbour queries; ties go to the lower index.
class KdTree {
 public:
  explicit KdTree(const std::vector<double>& xyz) : p_(xyz) {
    idx_.resize(xyz.size() / 3);
    std::iota(idx_.begin(), idx_.end(), std::size_t{0});
    if (!idx_.empty()) build(0, idx_.size());
  }

  std::size_t nearest(const double* q) const {
    Best best;
    if (!nodes_.empty()) search(0, q, best);
    return best.index;
  }

 private:
  struct Node {
    std::size_t begin, end;  // leaf range in idx_
    int axis = -1;           // -1: leaf
    double split = 0;
    std::size_t left = 0, right = 0;
  };
  struct Best {
    double d2 = std::numeric_limits<double>::infinity();
    std::size_t index = std::numeric_limits<std::size_t>::max();
  };
  static constexpr std::size_t kLeaf = 8;

  std::size_t build(std::size_t begin, std::size_t end) {
    const std::size_t id = nodes_.size();
    nodes_.push_back({begin, end});
    if (end - begin <= kLeaf) return id;
    double lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::numeric_limits<double>::infinity();
      hi[a] = -lo[a];
    }
    for (std::size_t k = begin; k < end; ++k)
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(lo[a], p_[3 * idx_[k] + a]);
        hi[a] = std::max(hi[a], p_[3 * idx_[k] + a]);
      }
    int axis = 0;
    for (int a = 1; a < 3; ++a)
      if (hi[a] - lo[a] > hi[axis] - lo[axis]) axis = a;
    if (!(hi[axis] > lo[axis])) return id;  // all points coincide: one leaf
    const std::size_t mid = begin + (end - begin) / 2;
    std::nth_element(idx_.begin() + begin, idx_.begin() + mid, idx_.begin() + end,
                     [&](std::size_t x, std::size_t y) {
                       const double px = p_[3 * x + axis], py = p_[3 * y + axis];
                       return px < py || (px == py && x < y);
                     });
    const double split = p_[3 * idx_[mid] + axis];
    const std::size_t left = build(begin, mid);
    const std::size_t right = build(mid, end);
    nodes_[id].axis = axis;
    nodes_[id].split = split;
    nodes_[id].left = left;
    nodes_[id].right = right;
    return id;
  }

  void search(std::size_t id, const double* q, Best& best) const {
    const Node& n = nodes_[id];
    if (n.axis < 0) {
      for (std::size_t k = n.begin; k < n.end; ++k) {
        const std::size_t i = idx_[k];
        const double dx = p_[3 * i] - q[0], dy = p_[3 * i + 1] - q[1], dz = p_[3 * i + 2] - q[2];
        const double d2 = dx * dx + dy * dy + dz * dz;
        if (d2 < best.d2 || (d2 == best.d2 && i < best.index)) {
          best.d2 = d2;
          best.index = i;
        }
      }
      return;
    }
    // Left holds coordinates <= split, right >= split.
    const double delta = q[n.axis] - n.split;
    const std::size_t first = delta < 0 ? n.left : n.right;
    const std::size_t second = delta < 0 ? n.right : n.left;
    search(first, q, best);
    if (delta * delta <= best.d2) search(second, q, best);
  }

  const std::vector<double>& p_;
  std::vector<std::size_t> idx_;
  std::vector<Node> nodes_;
};

//! The grid's box (given, or the splats' centres) into `res` (dims, origin, dx, empty cells).
//! Returns the box before padding: a given box also bounds which splats count.
std::array<std::array<double, 3>, 2> make_grid(const SplatSet& splats, const FillingOptions& o,
                                               FillingResult& res) {
  std::array<double, 3> lo, hi;
  if (o.has_box) {
    lo = o.box_lo;
    hi = o.box_hi;
  } else {
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::numeric_limits<double>::infinity();
      hi[a] = -lo[a];
    }
    for (std::size_t i = 0; i < splats.size(); ++i)
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(lo[a], splats.position[3 * i + a]);
        hi[a] = std::max(hi[a], splats.position[3 * i + a]);
      }
  }
  const double edge = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
  if (!(edge > 0) || !std::isfinite(edge))
    bad_option("the splats' centres span no volume (give a box)");
  const double dx = edge / o.n_grid;
  const int pad = o.has_box ? 0 : o.box_padding_cells;
  for (int a = 0; a < 3; ++a) {
    const int inside = std::max(1, static_cast<int>(std::ceil((hi[a] - lo[a]) / dx * (1 - 1e-12))));
    res.dims[a] = std::min(inside, o.n_grid) + 2 * pad;
    res.origin[a] = lo[a] - pad * dx;
  }
  res.dx = dx;
  const std::size_t ncells = static_cast<std::size_t>(res.dims[0]) * res.dims[1] * res.dims[2];
  res.cells.assign(ncells, FillCell::empty);
  res.density.assign(ncells, 0.0);
  return {lo, hi};
}

//! Adds splat p's density to the cells within its clamped support around cell c (seed eq. 11;
//! PhysGaussian's densify_grids): opacity x the mean of the kernel at each cell's 8 corners.
void add_splat_density(const SplatSet& splats, std::size_t p, const int c[3],
                       const FillingOptions& o, FillingResult& res, std::vector<double>& node) {
  const double dx = res.dx;
  const double var_floor = (0.01 * dx) * (0.01 * dx);
  const double* x = &splats.position[3 * p];
  const auto u = splats.covariance(p);
  Eigen::Matrix3d A;
  A << u[0], u[1], u[2], u[1], u[3], u[4], u[2], u[4], u[5];
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(A);
  Eigen::Vector3d lam = eig.eigenvalues();
  if (!(lam.maxCoeff() > 0) || lam.minCoeff() <= 1e-12 * lam.maxCoeff()) ++res.degenerate_splats;
  for (int a = 0; a < 3; ++a) lam[a] = std::max(lam[a], var_floor);
  const Eigen::Matrix3d Q = eig.eigenvectors();
  const Eigen::Matrix3d Ainv = Q * lam.cwiseInverse().asDiagonal() * Q.transpose();
  const double reach = o.support_sigmas * std::sqrt(lam.maxCoeff()) / dx;
  int r = static_cast<int>(std::min(std::ceil(reach), static_cast<double>(o.max_support_cells)));
  r = std::max(r, 1);
  if (reach > o.max_support_cells) ++res.clamped_splats;

  // Kernel at the (2r + 2)^3 corners of the cells c - r .. c + r.
  const int m = 2 * r + 2;
  node.assign(static_cast<std::size_t>(m) * m * m, 0.0);
  for (int k = 0; k < m; ++k)
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < m; ++i) {
        const Eigen::Vector3d d(res.origin[0] + (c[0] - r + i) * dx - x[0],
                                res.origin[1] + (c[1] - r + j) * dx - x[1],
                                res.origin[2] + (c[2] - r + k) * dx - x[2]);
        node[(static_cast<std::size_t>(k) * m + j) * m + i] = std::exp(-0.5 * d.dot(Ainv * d));
      }
  const double w = splats.opacity[p] / 8.0;
  const int nx = res.dims[0], ny = res.dims[1], nz = res.dims[2];
  for (int k = 0; k + 1 < m; ++k) {
    const int gk = c[2] - r + k;
    if (gk < 0 || gk >= nz) continue;
    for (int j = 0; j + 1 < m; ++j) {
      const int gj = c[1] - r + j;
      if (gj < 0 || gj >= ny) continue;
      for (int i = 0; i + 1 < m; ++i) {
        const int gi = c[0] - r + i;
        if (gi < 0 || gi >= nx) continue;
        double s = 0;
        for (int dk = 0; dk < 2; ++dk)
          for (int dj = 0; dj < 2; ++dj)
            for (int di = 0; di < 2; ++di)
              s += node[(static_cast<std::size_t>(k + dk) * m + j + dj) * m + i + di];
        res.density[res.cell_index(gi, gj, gk)] += w * s;
      }
    }
  }
}

//! Every splat's density on the grid; returns the original Gaussians centred in each cell.
std::vector<int> splat_density(const SplatSet& splats, const FillingOptions& o,
                               const std::array<std::array<double, 3>, 2>& box, FillingResult& res,
                               Ticker& ticker) {
  const std::size_t n = splats.size();
  std::vector<int> count(res.cells.size(), 0);
  std::vector<double> node;
  for (std::size_t p = 0; p < n; ++p) {
    ticker.tick("density, splat", p, n);
    const double* x = &splats.position[3 * p];
    int c[3];
    bool inside = true;
    for (int a = 0; a < 3; ++a) {
      if (o.has_box && !(x[a] > box[0][a] && x[a] < box[1][a])) inside = false;
      const double f = std::floor((x[a] - res.origin[a]) / res.dx);
      c[a] = static_cast<int>(std::clamp(f, 0.0, static_cast<double>(res.dims[a] - 1)));
    }
    if (!inside) continue;
    ++res.splats_in_box;
    ++count[res.cell_index(c[0], c[1], c[2])];
    add_splat_density(splats, p, c, o, res, node);
  }
  return count;
}

//! New particles at hashed positions inside their cells, capped at max_particles.
class Placer {
 public:
  Placer(const FillingOptions& o, const FillingResult& res) : o_(o), res_(res) {}

  void place(std::size_t cell, int i, int j, int k, int how_many) {
    if (positions.size() / 3 + how_many > o_.max_particles)
      bad_option(fmt::format("more than max_particles = {} particles", o_.max_particles));
    const double dx = res_.dx;
    for (int q = 0; q < how_many; ++q) {
      const std::uint64_t h = mix(mix(o_.seed) ^ mix(cell * 1024 + static_cast<std::uint64_t>(q)));
      const double u[3] = {unit(mix(h ^ 1)), unit(mix(h ^ 2)), unit(mix(h ^ 3))};
      positions.push_back(res_.origin[0] + (i + u[0]) * dx);
      positions.push_back(res_.origin[1] + (j + u[1]) * dx);
      positions.push_back(res_.origin[2] + (k + u[2]) * dx);
    }
  }

  std::vector<double> positions;

 private:
  const FillingOptions& o_;
  const FillingResult& res_;
};

//! Marks occupied and surface cells (PhysGaussian's fill_dense_grids) and tops the surface cells
//! up to max_particles_per_cell.
void fill_surface_cells(const FillingOptions& o, const std::vector<int>& count, FillingResult& res,
                        Placer& placer) {
  for (int k = 0; k < res.dims[2]; ++k)
    for (int j = 0; j < res.dims[1]; ++j)
      for (int i = 0; i < res.dims[0]; ++i) {
        const std::size_t cell = res.cell_index(i, j, k);
        if (count[cell] > 0) res.cells[cell] = FillCell::occupied;
        if (!(res.density[cell] > o.density_threshold)) continue;
        res.cells[cell] = FillCell::surface;
        ++res.surface_cells;
        const int diff = o.max_particles_per_cell - count[cell];
        if (o.fill_surface_cells && diff > 0) {
          placer.place(cell, i, j, k, diff);
          res.surface_particles += diff;
        }
      }
}

//! The interior test of every cell (PhysGaussian's internal_filling): its rays along the axis
//! directions (but the excluded one) all reach a cell above search_threshold, and its ray along
//! ray_cast_direction rises above it an odd number of times. Each direction is one sweep of every
//! grid line from its far end, so the test costs O(cells) instead of O(cells n_grid).
std::vector<std::uint8_t> interior_test(const FillingOptions& o, const FillingResult& res) {
  std::vector<std::uint8_t> ok(res.cells.size(), 1);
  const std::array<int, 3> stride{1, res.dims[0], res.dims[0] * res.dims[1]};
  auto above = [&](std::size_t cell) { return res.density[cell] > o.search_threshold; };
  auto for_each_line = [&](int axis, auto&& fn) {
    const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
    for (int v = 0; v < res.dims[a2]; ++v)
      for (int u = 0; u < res.dims[a1]; ++u) {
        int idx[3];
        idx[axis] = 0;
        idx[a1] = u;
        idx[a2] = v;
        fn(res.cell_index(idx[0], idx[1], idx[2]), static_cast<std::size_t>(stride[axis]),
           res.dims[axis]);
      }
  };
  for (int dir = 0; dir < 6; ++dir) {
    if (dir == o.search_exclude_direction) continue;
    const bool positive = dir % 2 == 0;
    for_each_line(dir / 2, [&](std::size_t start, std::size_t step, int len) {
      bool seen = false;  // a cell above the threshold strictly beyond the current one
      for (int t = 0; t < len; ++t) {
        const int m = positive ? len - 1 - t : t;
        const std::size_t cell = start + step * m;
        if (!seen) ok[cell] = 0;
        seen = seen || above(cell);
      }
    });
  }
  if (o.ray_cast_direction < 0) return ok;
  const bool positive = o.ray_cast_direction % 2 == 0;
  for_each_line(o.ray_cast_direction / 2, [&](std::size_t start, std::size_t step, int len) {
    // Crossings from cell m: the ray starts "below" (an empty cell), so a rise at the next
    // cell m+1 counts when it is above, and at q >= m+2 when q is above and q-1 is not.
    int rises = 0;  // rises at q >= m + 2
    for (int t = 0; t < len; ++t) {
      const int m = positive ? len - 1 - t : t;
      const int next = positive ? m + 1 : m - 1;
      const bool has_next = next >= 0 && next < len;
      const bool next_above = has_next && above(start + step * next);
      const int crossings = rises + (next_above ? 1 : 0);
      if (crossings % 2 == 0) ok[start + step * m] = 0;
      if (next_above && !above(start + step * m)) ++rises;
    }
  });
  return ok;
}

//! Fills the empty cells that pass the interior test with max_particles_per_cell particles.
void fill_interior_cells(const FillingOptions& o, FillingResult& res, Placer& placer) {
  const std::vector<std::uint8_t> ok = interior_test(o, res);
  for (int k = 0; k < res.dims[2]; ++k)
    for (int j = 0; j < res.dims[1]; ++j)
      for (int i = 0; i < res.dims[0]; ++i) {
        const std::size_t cell = res.cell_index(i, j, k);
        if (res.cells[cell] != FillCell::empty || !ok[cell]) continue;
        res.cells[cell] = FillCell::interior;
        ++res.interior_cells;
        placer.place(cell, i, j, k, o.max_particles_per_cell);
        res.interior_particles += o.max_particles_per_cell;
      }
}

//! The new particles at `positions` with the attributes of the nearest original Gaussian (all
//! of them, as PhysGaussian's init_filled_particles), found in a k-d tree.
void nearest_attributes(const SplatSet& splats, std::vector<double> positions, FillingResult& res,
                        Ticker& ticker) {
  SplatSet& out = res.particles;
  const std::size_t added = positions.size() / 3;
  const std::size_t per_sh = 3 * static_cast<std::size_t>(splats.coefficients());
  out.sh_degree = splats.sh_degree;
  out.position = std::move(positions);
  out.scale.assign(3 * added, res.particle_radius);
  out.rotation.resize(4 * added);
  out.opacity.resize(added);
  out.sh.resize(per_sh * added);
  const KdTree tree(splats.position);
  for (std::size_t q = 0; q < added; ++q) {
    ticker.tick("nearest Gaussian, particle", q, added);
    const std::size_t near = tree.nearest(&out.position[3 * q]);
    out.rotation[4 * q] = 1;
    out.rotation[4 * q + 1] = out.rotation[4 * q + 2] = out.rotation[4 * q + 3] = 0;
    out.opacity[q] = splats.opacity[near];
    std::copy_n(splats.sh.begin() + per_sh * near, per_sh, out.sh.begin() + per_sh * q);
  }
}

}  // namespace

FillingResult fill_interior(const SplatSet& splats, const FillingOptions& o) {
  check_options(o);
  check_splats(splats);
  const auto t0 = Clock::now();
  Ticker ticker(o.progress_interval);
  FillingResult res;
  const auto box = make_grid(splats, o, res);
  const std::vector<int> count = splat_density(splats, o, box, res, ticker);
  res.seconds_density = seconds_since(t0);
  const auto t1 = Clock::now();

  const double dx = res.dx;
  res.particle_volume = dx * dx * dx / o.max_particles_per_cell;
  res.particle_radius = std::cbrt(3 * res.particle_volume / (4 * kPi));
  Placer placer(o, res);
  fill_surface_cells(o, count, res, placer);
  fill_interior_cells(o, res, placer);
  res.seconds_cells = seconds_since(t1);
  const auto t2 = Clock::now();

  nearest_attributes(splats, std::move(placer.positions), res, ticker);
  res.seconds_attributes = seconds_since(t2);
  res.seconds_total = seconds_since(t0);
  if (res.seconds_total > o.progress_interval || res.clamped_splats > 0)
    log::info(
        "particle filling: {} surface + {} interior particles on {}x{}x{} cells in {:.1f} s "
        "({} degenerate, {} clamped Gaussians)",
        res.surface_particles, res.interior_particles, res.dims[0], res.dims[1], res.dims[2],
        res.seconds_total, res.degenerate_splats, res.clamped_splats);
  return res;
}

}  // namespace gen4d::gaussians
