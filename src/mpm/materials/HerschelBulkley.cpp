// herschel_bulkley (paste; PhysGaussian App. B.6, Yue et al. 2015), viscoplastic flow with
// StVK-Hencky elasticity, a return map in principal Hencky strain.
//
// Elasticity: F = U Sigma V^T (signed SVD), e = log(Sigma), s = dev(tau) = 2 mu dev(e).
//
// Flow law and its tensor form. In simple shear, L = gamma_dot e1 (x) e2, the rate of
// deformation D = gamma_dot/2 (e1 (x) e2 + e2 (x) e1) has |D| = gamma_dot / sqrt(2), and a shear
// stress tau_12 = t gives s = t (e1 (x) e2 + e2 (x) e1) with |s| = sqrt(2) t. The
// Herschel-Bulkley law t = tau_y + K gamma_dot^n therefore reads, with the equivalent shear
// stress |s| / sqrt(2), the equivalent plastic shear rate sqrt(2) |D_p| and flow along s / |s|:
//   |s| / sqrt(2) <= tau_y:  D_p = 0;
//   otherwise:               |s| / sqrt(2) = tau_y + K (sqrt(2) |D_p|)^n,  D_p = |D_p| s / |s|.
// Backward Euler over dt in Hencky strain (s is parallel to dev e, so the return is radial):
//   m = |dev e_trial|, Dl = dt |D_p| >= 0, dev e = dev e_trial (1 - Dl / m), tr(e) unchanged,
//   h(Dl) = 2 mu (m - Dl) / sqrt(2) - tau_y - K (sqrt(2) Dl / dt)^n = 0,
// yield when h(0) = sqrt(2) mu m - tau_y > 0. h is strictly decreasing with h(m) <= 0, so the root
// in (0, m] is unique: closed form for n = 1 (Bingham),
//   Dl = (sqrt(2) mu m - tau_y) / (sqrt(2) mu + sqrt(2) K / dt),
// else Newton with a bisection safeguard to |h| <= 1e-14 sqrt(2) mu m. F <- U exp(e) V^T.
// For n = 1 this is the seed's s = s_tr - (s_tr - sqrt(2/3) sigma_Y) / (1 + eta / (2 mu dt)) with
// the von Mises tensile yield stress sigma_Y = sqrt(3) tau_y and eta = 2 K.
// State slot 0 accumulates the plastic shear strain gamma_p += sqrt(2) Dl (engineering shear, so
// in simple shear its rate is gamma_dot_p). With dt <= 0 a positive K admits no flow.
#include <algorithm>
#include <cmath>
#include <limits>

#include "mpm/materials/Models.hpp"

namespace gen4d::mpm {

namespace {

using detail::Mat3;
using detail::Vec3;

constexpr double kSqrt2 = 1.41421356237309504880168872420969808;

struct HerschelBulkleyConstants {
  double mu, lambda;
  double tau_y, K, n;
};

// Dl in [0, m] with h(Dl) = 0; h(0) > 0 is known.
inline double herschel_bulkley_return(const HerschelBulkleyConstants& c, double m, double dt) {
  const double a = kSqrt2 * c.mu;        // h(Dl) = a (m - Dl) - tau_y - K (sqrt(2) Dl / dt)^n
  const double rigid = m - c.tau_y / a;  // the root for K = 0, an upper bound otherwise
  if (c.K == 0) return rigid;
  if (!(dt > 0)) return 0.0;
  if (c.n == 1) return (a * m - c.tau_y) / (a + kSqrt2 * c.K / dt);
  const double r = kSqrt2 / dt;
  auto eval = [&](double x, double& h, double& dh) {
    const double visc = c.K * std::pow(r * x, c.n);
    h = a * (m - x) - c.tau_y - visc;
    dh = -a - (x > 0 ? c.n * visc / x : std::numeric_limits<double>::infinity());
  };
  return detail::decreasing_root(eval, rigid, rigid, 1e-14 * a * m);
}

inline void herschel_bulkley_kernel(const HerschelBulkleyConstants& c, const Mat3& U, const Vec3& s,
                                    const Mat3& V, double* Fp, double* state, double* taup,
                                    double dt) {
  Vec3 e = detail::hencky_strain(s);
  const Vec3 eh = detail::dev3(e);
  const double m = detail::norm3(eh);
  if (kSqrt2 * c.mu * m > c.tau_y) {
    const double dl = herschel_bulkley_return(c, m, dt);
    if (dl > 0) {
      materials::radial_return(e, eh, m, dl);
      state[0] += kSqrt2 * dl;
      detail::store_hencky_return(U, e, V, c.mu, c.lambda, Fp, taup);
      return;
    }
  }
  detail::store_hencky_return(U, e, V, c.mu, c.lambda, nullptr, taup);
}

using HerschelBulkleyBase =
    ReturnMap<HenckyReturnModel, HerschelBulkleyConstants, herschel_bulkley_kernel>;

class HerschelBulkley final : public HerschelBulkleyBase {
 public:
  explicit HerschelBulkley(const MaterialParams& p) : HerschelBulkleyBase(p) {
    c_.tau_y = p.get("yield_stress");
    c_.K = p.get("consistency");
    c_.n = p.get("flow_index", 1.0);
    detail::check_value(p, "yield_stress", c_.tau_y >= 0, ">= 0 (Pa, shear yield stress)");
    detail::check_value(p, "consistency", c_.K >= 0, ">= 0 (Pa s^n)");
    if (p.has("flow_index")) detail::check_value(p, "flow_index", c_.n > 0, "> 0");
  }
  std::string name() const override { return "herschel_bulkley"; }
  std::vector<std::string> state_names() const override { return {"plastic_strain"}; }
};

}  // namespace

void register_herschel_bulkley() {
  detail::add_model<HerschelBulkley>("herschel_bulkley",
                                     {"yield_stress", "consistency", "flow_index"});
}

}  // namespace gen4d::mpm
