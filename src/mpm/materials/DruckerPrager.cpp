// drucker_prager (sand; PhysGaussian App. B.4, Klar et al. 2016 "Drucker-Prager elastoplasticity
// for sand animation"), StVK-Hencky elasticity with a return map in principal Hencky strain.
//
// Elasticity: F = U Sigma V^T (signed SVD), e = log(Sigma), tau = U (2 mu e + lambda tr(e) I) U^T,
// so dev(tau) = 2 mu dev(e) and tr(tau) = (3 lambda + 2 mu) tr(e) = K3 tr(e).
//
// Yield surface (Drucker-Prager cone matched to Mohr-Coulomb on the compressive meridian, in
// Klar's normalisation; phi = friction angle, c = cohesion):
//   f(tau) = |dev tau| + alpha tr(tau) - k <= 0,
//   alpha = sqrt(2/3) 2 sin(phi) / (3 - sin(phi)),   k = sqrt(2/3) 6 c cos(phi) / (3 - sin(phi)).
// (|dev tau| = sqrt(2 J2), so this is sqrt(J2) + A I1 <= B with the textbook A, B.) For c = 0 it is
// Klar's cone with the apex at tau = 0; cohesion moves the apex to the hydrostatic tension
// tr(tau)/3 = c cot(phi), i.e. to tr(e) = tr_apex = k / (alpha K3), the volumetric strain shift of
// the literature (ziran's "cohesion" strain). phi = 0 with c > 0 has no apex (a cohesive von Mises
// cylinder |dev tau| <= k); phi = 0 with c = 0 keeps Klar's apex at zero.
//
// Volume correction (Klar et al., "volume correction"): state slot 0 holds v_c = log J_P, the
// plastic volume gained by projections to the apex (the material separated). It is added to the
// trial strain, e = log(Sigma) + v_c / 3, so that re-compression first closes that gap stress-free.
//
// Return map on e (n = |dev e|, delta_gamma = n + (alpha K3 tr(e) - k) / (2 mu), Klar's delta_gamma
// with the cohesion term):
//   1. tr(e) > tr_apex (tension past the apex): e <- (tr_apex / 3) 1 (the stress-free state for
//      c = 0, else the cohesion apex); v_c <- tr(e) - tr_apex; plastic shear += n.
//   2. delta_gamma <= 0 (inside the cone): e unchanged; v_c <- 0.
//   3. otherwise (onto the cone, along dev e): e <- e - delta_gamma dev(e) / n; v_c <- 0;
//      plastic shear += delta_gamma. Then f = 2 mu (n - delta_gamma) + alpha K3 tr(e) - k = 0.
// F <- U exp(e) V^T. State slot 1 accumulates the plastic shear (Hencky strain norm removed).
#include <algorithm>
#include <cmath>
#include <limits>

#include "mpm/materials/Models.hpp"

namespace gen4d::mpm {

namespace {

using detail::Mat3;
using detail::Vec3;

struct DruckerPragerConstants {
  double mu, lambda;
  double alpha;    //!< cone slope
  double k;        //!< cohesion term, Pa
  double K3;       //!< 3 lambda + 2 mu
  double tr_apex;  //!< tr(e) of the apex (0 without cohesion, +inf for a cylinder)
};

// Return map of one particle given the signed SVD U diag(s) V^T of its F: F (9) and state
// (kStateSize) in place, tau (9) out.
inline void drucker_prager_kernel(const DruckerPragerConstants& c, const Mat3& U, const Vec3& s,
                                  const Mat3& V, double* Fp, double* state, double* taup,
                                  double /*dt: rate-independent*/) {
  Vec3 e = detail::hencky_strain(s);
  const double vc = state[0];
  for (int k = 0; k < 3; ++k) e[k] += vc / 3.0;
  const double tr = detail::trace3(e);
  const Vec3 eh = detail::dev3(e);
  const double n = detail::norm3(eh);
  bool changed = vc != 0.0;
  if (tr > c.tr_apex) {
    e = Vec3{{c.tr_apex / 3.0, c.tr_apex / 3.0, c.tr_apex / 3.0}};
    state[0] = tr - c.tr_apex;
    state[1] += n;
    changed = true;
  } else {
    const double dgamma = n + (c.alpha * c.K3 * tr - c.k) / (2 * c.mu);
    if (dgamma > 0 && n > 0) {
      materials::radial_return(e, eh, n, dgamma);
      state[1] += dgamma;
      changed = true;
    }
    state[0] = 0.0;
  }
  detail::store_hencky_return(U, e, V, c.mu, c.lambda, changed ? Fp : nullptr, taup);
}

using DruckerPragerBase =
    ReturnMap<HenckyReturnModel, DruckerPragerConstants, drucker_prager_kernel>;

class DruckerPrager final : public DruckerPragerBase {
 public:
  explicit DruckerPrager(const MaterialParams& p) : DruckerPragerBase(p) {
    const double phi = p.get("friction_angle");
    const double cohesion = p.get("cohesion", 0.0);
    detail::check_value(p, "friction_angle", phi >= 0 && phi < 90, "in [0, 90) degrees");
    if (p.has("cohesion")) detail::check_value(p, "cohesion", cohesion >= 0, ">= 0 (Pa)");
    constexpr double kDegree = 3.14159265358979323846 / 180.0;
    const double sin_phi = std::sin(phi * kDegree), cos_phi = std::cos(phi * kDegree);
    c_.alpha = std::sqrt(2.0 / 3.0) * 2 * sin_phi / (3 - sin_phi);
    c_.k = std::sqrt(2.0 / 3.0) * 6 * cohesion * cos_phi / (3 - sin_phi);
    c_.K3 = 3 * lambda_ + 2 * mu_;
    c_.tr_apex = c_.alpha > 0 ? c_.k / (c_.alpha * c_.K3)
                 : c_.k > 0   ? std::numeric_limits<double>::infinity()
                              : 0.0;
  }
  std::string name() const override { return "drucker_prager"; }
  std::vector<std::string> state_names() const override {
    return {"volume_correction", "plastic_shear_strain"};
  }
};

}  // namespace

void register_drucker_prager() {
  detail::add_model<DruckerPrager>("drucker_prager", {"friction_angle", "cohesion"});
}

}  // namespace gen4d::mpm
