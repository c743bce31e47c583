//! Static colliders: signed distance and outward normal of a plane or of the outside of a box,
//! and the contact response that keeps a node out of the obstacle with Coulomb friction.
#pragma once

#include "core/Config.hpp"

namespace gen4d::elastogen {

class Collider {
 public:
  explicit Collider(const ColliderConfig& c);

  //! Signed distance from p to the obstacle's surface (negative inside the obstacle) and, in
  //! n, the unit normal pointing out of the obstacle at the closest surface point. Inside a
  //! box the closest face wins (the first in -x, +x, -y, +y, -z, +z order on ties).
  double distance(const double* p, double* n) const;
  double friction() const { return mu_; }

  //! Contact response of one node that moved from xn to x during a step of any length dt:
  //! if x lies inside the obstacle, it is moved onto the surface along the normal, and its
  //! tangential displacement over the step (the velocity relative to the static obstacle,
  //! times dt) is shortened by mu times the normal push-out (Coulomb: |dv_t| <= mu |dv_n|),
  //! stopping at zero (stick). Returns the penetration depth before the push-out (0: none).
  double resolve(const double* xn, double* x) const;

 private:
  bool plane_;
  double point_[3] = {0, 0, 0}, normal_[3] = {0, 0, 1};  // plane; normal_ has unit length
  BoxRegion box_;
  double mu_;
};

}  // namespace gen4d::elastogen
