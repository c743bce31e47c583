#include "elastogen/Collider.hpp"

#include <algorithm>
#include <cmath>

namespace gen4d::elastogen {

Collider::Collider(const ColliderConfig& c)
    : plane_(c.type == "plane"), box_(c.box), mu_(c.friction) {
  const double len =
      std::sqrt(c.normal[0] * c.normal[0] + c.normal[1] * c.normal[1] + c.normal[2] * c.normal[2]);
  for (int d = 0; d < 3; ++d) {
    point_[d] = c.point[d];
    normal_[d] = c.normal[d] / len;
  }
}

double Collider::distance(const double* p, double* n) const {
  if (plane_) {
    for (int d = 0; d < 3; ++d) n[d] = normal_[d];
    return (p[0] - point_[0]) * normal_[0] + (p[1] - point_[1]) * normal_[1] +
           (p[2] - point_[2]) * normal_[2];
  }
  const Vec3d &lo = box_.lo, &hi = box_.hi;
  if (box_.contains({p[0], p[1], p[2]})) {
    // Inside (or on the surface): the nearest face, with its outward normal.
    double best = 0;
    int face = -1;
    for (int d = 0; d < 3; ++d)
      for (int side = 0; side < 2; ++side) {
        const double gap = side ? hi[d] - p[d] : p[d] - lo[d];
        if (face < 0 || gap < best) {
          best = gap;
          face = 2 * d + side;
        }
      }
    for (int d = 0; d < 3; ++d) n[d] = 0;
    n[face / 2] = face % 2 ? 1.0 : -1.0;
    return -best;
  }
  // Outside: distance to the closest point of the box.
  double r[3], len2 = 0;
  for (int d = 0; d < 3; ++d) {
    r[d] = p[d] - std::min(std::max(p[d], lo[d]), hi[d]);
    len2 += r[d] * r[d];
  }
  const double len = std::sqrt(len2);
  for (int d = 0; d < 3; ++d) n[d] = r[d] / len;
  return len;
}

double Collider::resolve(const double* xn, double* x) const {
  double n[3];
  const double phi = distance(x, n);
  if (!(phi < 0)) return 0;
  // Tangential part of the step's displacement, taken before the push-out.
  double u[3], tangent[3];
  for (int d = 0; d < 3; ++d) u[d] = x[d] - xn[d];
  const double un = u[0] * n[0] + u[1] * n[1] + u[2] * n[2];
  for (int d = 0; d < 3; ++d) tangent[d] = u[d] - un * n[d];
  const double ut =
      std::sqrt(tangent[0] * tangent[0] + tangent[1] * tangent[1] + tangent[2] * tangent[2]);
  // Push-out along the normal: the normal velocity changes by -phi / dt.
  for (int d = 0; d < 3; ++d) x[d] -= phi * n[d];
  if (!plane_) {
    // Land exactly on the face (n is an axis there, so the tangent has no component on it).
    const int a = n[0] != 0 ? 0 : n[1] != 0 ? 1 : 2;
    x[a] = n[a] > 0 ? box_.hi[a] : box_.lo[a];
  }
  // Coulomb friction: the tangential velocity loses at most mu |dv_n|, down to zero.
  if (ut > 0) {
    const double cut = std::min(1.0, mu_ * -phi / ut);
    for (int d = 0; d < 3; ++d) x[d] -= cut * tangent[d];
  }
  return -phi;
}

}  // namespace gen4d::elastogen
