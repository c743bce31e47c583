// Centre-sampled voxelization.
//
// A cell is solid iff its centre is inside. Unlike "any overlap" (which inflates the solid by
// up to a cell on every side) or "fully covered" (which erodes it), centre sampling is
// unbiased: the cells gained and lost along a smooth boundary cancel to first order, so the
// volume error is far below one layer of boundary cells (a few 0.1% at 12 cells per radius
// for a ball, where a one-cell layer is 25%). It also makes each
// cell's state a function of its global index alone, which lets every rank voxelize its own
// box (with ghosts) and agree exactly with its neighbours.
#include "geometry/Shape.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace gen4d::geometry {
namespace {

// Cells whose centre origin + h*(i + 1/2) may lie in [lo, hi], widened by one cell so that
// rounding here can never drop a cell; inside() makes the final decision.
void candidate_range(double lo, double hi, double origin, double h, long cell_lo, long cell_hi,
                     long& first, long& last) {
  const double a = std::floor((lo - origin) / h - 0.5) - 1;
  const double b = std::ceil((hi - origin) / h - 0.5) + 2;
  first = static_cast<long>(std::clamp(a, double(cell_lo), double(cell_hi)));
  last = static_cast<long>(std::clamp(b, double(cell_lo), double(cell_hi)));
}

}  // namespace

void voxelize(const Shape& s, const Eigen::Vector3d& origin, double h,
              const std::array<long, 3>& cell_lo, const std::array<long, 3>& cell_hi,
              std::vector<std::uint8_t>& occ) {
  if (!(h > 0)) throw std::invalid_argument("voxelize: cell size must be positive");
  voxelize(s, origin, Eigen::Vector3d(h, h, h), cell_lo, cell_hi, occ);
}

void voxelize(const Shape& s, const Eigen::Vector3d& origin, const Eigen::Vector3d& spacing,
              const std::array<long, 3>& cell_lo, const std::array<long, 3>& cell_hi,
              std::vector<std::uint8_t>& occ) {
  for (int d = 0; d < 3; ++d)
    if (!(spacing[d] > 0)) throw std::invalid_argument("voxelize: cell size must be positive");
  std::array<long, 3> n{};
  for (int d = 0; d < 3; ++d) {
    if (cell_hi[d] < cell_lo[d]) throw std::invalid_argument("voxelize: cell_hi < cell_lo");
    n[d] = cell_hi[d] - cell_lo[d];
  }
  occ.assign(static_cast<std::size_t>(n[0] * n[1] * n[2]), 0);
  const Aabb box = s.bounds();
  if (box.empty() || occ.empty()) return;
  std::array<long, 3> first{}, last{};
  for (int d = 0; d < 3; ++d)
    candidate_range(box.lo[d], box.hi[d], origin[d], spacing[d], cell_lo[d], cell_hi[d], first[d],
                    last[d]);
  Eigen::Vector3d p;
  for (long k = first[2]; k < last[2]; ++k) {
    p.z() = origin.z() + spacing.z() * (static_cast<double>(k) + 0.5);
    for (long j = first[1]; j < last[1]; ++j) {
      p.y() = origin.y() + spacing.y() * (static_cast<double>(j) + 0.5);
      std::uint8_t* row = occ.data() + ((k - cell_lo[2]) * n[1] + (j - cell_lo[1])) * n[0];
      for (long i = first[0]; i < last[0]; ++i) {
        p.x() = origin.x() + spacing.x() * (static_cast<double>(i) + 0.5);
        row[i - cell_lo[0]] = s.inside(p) ? 1 : 0;
      }
    }
  }
}

long count_solid(const std::vector<std::uint8_t>& occ) {
  return static_cast<long>(
      std::count_if(occ.begin(), occ.end(), [](std::uint8_t v) { return v != 0; }));
}

}  // namespace gen4d::geometry
