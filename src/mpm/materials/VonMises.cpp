// von_mises (metal; PhysGaussian App. B.5), StVK-Hencky elasticity with J2 plasticity by radial
// return in principal Hencky strain, linear isotropic or Johnson-Cook hardening.
//
// Elasticity: F = U Sigma V^T (signed SVD), e = log(Sigma), s = dev(tau) = 2 mu dev(e).
// Yield: f = |s| - sqrt(2/3) sigma_y(eps_p, eps_p_dot, T) <= 0 (|.| Frobenius; in uniaxial stress
// |s| = sqrt(2/3) |sigma|, so sigma_y is the uniaxial yield stress). The seed's
// delta_gamma = |dev e| - tau_Y / (2 mu) is the perfectly plastic case with tau_Y = sqrt(2/3)
// sigma_y.
//
// Flow: plastic Hencky strain increment delta_gamma dev(e)/|dev e| (associative, isochoric, so the
// volume stays elastic); equivalent plastic strain increment d_eps_p = sqrt(2/3) delta_gamma. The
// consistent (backward Euler) return solves for delta_gamma in [0, |dev e|]
//   g(dg) = 2 mu (|dev e_trial| - dg) - sqrt(2/3) sigma_y(eps_p + sqrt(2/3) dg,
//                                                         sqrt(2/3) dg / dt, T) = 0,
// then dev(e) <- dev(e_trial) (1 - dg / |dev e_trial|), tr(e) unchanged, F <- U exp(e) V^T.
//   Linear hardening sigma_y = sigma_y0 + H eps_p: dg = f_trial / (2 mu + 2 H / 3), closed form.
//   Johnson-Cook sigma_y = (A + B eps_p^n) (1 + C ln(max(eps_p_dot / eps_dot0, 1))) (1 - T*^m),
//     T* = clamp((T - T_room) / (T_melt - T_room), 0, 1) (no thermal term without
//     melt_temperature): g is strictly decreasing with g(0) > 0 >= g(|dev e|), solved by Newton
//     with a bisection safeguard to |g| <= 1e-14 2 mu |dev e_trial|.
// The temperature is explicit (staggered): sigma_y uses T at the start of the step; afterwards,
// with specific_heat given, T += taylor_quinney sigma_y d_eps_p / (density specific_heat), the
// plastic work s : d(eps^p) = sigma_y d_eps_p per reference volume turned into heat. State: 0
// eps_p, 1 temperature (K), 2 eps_p rate of the last update (0 when it was elastic).
#include <algorithm>
#include <cmath>
#include <limits>

#include "mpm/materials/Models.hpp"

namespace gen4d::mpm {

namespace {

using detail::Mat3;
using detail::Vec3;

using materials::kSqrt23;

struct VonMisesConstants {
  double mu, lambda, density;
  bool johnson_cook;
  double sigma_y0, H;                    // linear hardening
  double A, B, n, C, m, rate0;           // Johnson-Cook
  double T_room, T_melt;                 // T_melt = +inf: no thermal softening
  double taylor_quinney, specific_heat;  // specific_heat = 0: no heating

  double thermal_factor(double T) const {
    if (!johnson_cook || !std::isfinite(T_melt)) return 1.0;
    const double Ts = std::clamp((T - T_room) / (T_melt - T_room), 0.0, 1.0);
    return 1.0 - std::pow(Ts, m);
  }
  //! Flow stress and its derivative d sigma_y / d dg along the return, at dg (rate = c dg / dt).
  void flow_stress(double eps_p, double dg, double dt, double thermal, double& sy,
                   double& dsy) const {
    if (!johnson_cook) {
      sy = sigma_y0 + H * (eps_p + kSqrt23 * dg);
      dsy = H * kSqrt23;
      return;
    }
    const double ep = eps_p + kSqrt23 * dg;
    const double hard = A + B * std::pow(ep, n);
    // d/d dg of B ep^n: infinite at ep = 0 for n < 1 (the Newton step then falls back to
    // bisection).
    const double dhard = B == 0   ? 0.0
                         : ep > 0 ? B * n * std::pow(ep, n - 1) * kSqrt23
                         : n < 1  ? std::numeric_limits<double>::infinity()
                         : n == 1 ? B * kSqrt23
                                  : 0.0;
    const double rate = dt > 0 ? kSqrt23 * dg / dt : 0.0;
    const bool rate_on = C > 0 && rate > rate0;
    const double rf = rate_on ? 1 + C * std::log(rate / rate0) : 1.0;
    const double drf = rate_on ? C / dg : 0.0;
    sy = hard * rf * thermal;
    dsy = thermal > 0 ? (dhard * rf + hard * drf) * thermal : 0.0;
  }
};

// Solves g(dg) = 0 on [0, nrm] for Johnson-Cook (g(0) = f_trial > 0, g(nrm) <= 0), starting
// from the perfectly plastic step at the current flow stress.
inline double johnson_cook_return(const VonMisesConstants& c, double nrm, double eps_p, double dt,
                                  double thermal, double f_trial) {
  const double two_mu = 2 * c.mu;
  auto eval = [&](double x, double& g, double& dg) {
    double sy, dsy;
    c.flow_stress(eps_p, x, dt, thermal, sy, dsy);
    g = two_mu * (nrm - x) - kSqrt23 * sy;
    dg = -two_mu - kSqrt23 * dsy;
  };
  return detail::decreasing_root(eval, nrm, std::min(f_trial / two_mu, nrm), 1e-14 * two_mu * nrm);
}

inline void von_mises_kernel(const VonMisesConstants& c, const Mat3& U, const Vec3& s,
                             const Mat3& V, double* Fp, double* state, double* taup, double dt) {
  Vec3 e = detail::hencky_strain(s);
  const Vec3 eh = detail::dev3(e);
  const double nrm = detail::norm3(eh);
  const double eps_p = state[0], T = state[1];
  const double thermal = c.thermal_factor(T);
  double sy0, dsy;
  c.flow_stress(eps_p, 0.0, dt, thermal, sy0, dsy);
  const double f_trial = 2 * c.mu * nrm - kSqrt23 * sy0;
  if (f_trial > 0 && nrm > 0) {
    const double dg = c.johnson_cook ? johnson_cook_return(c, nrm, eps_p, dt, thermal, f_trial)
                                     : materials::j2_linear_multiplier(f_trial, c.mu, c.H);
    materials::radial_return(e, eh, nrm, dg);
    const double deps = kSqrt23 * dg;
    double sy;
    c.flow_stress(eps_p, dg, dt, thermal, sy, dsy);
    state[0] = eps_p + deps;
    if (c.specific_heat > 0)
      state[1] = T + c.taylor_quinney * sy * deps / (c.density * c.specific_heat);
    state[2] = dt > 0 ? deps / dt : 0.0;
  } else {
    state[2] = 0.0;
    Fp = nullptr;  // elastic: F stays
  }
  detail::store_hencky_return(U, e, V, c.mu, c.lambda, Fp, taup);
}

using VonMisesBase = ReturnMap<HenckyReturnModel, VonMisesConstants, von_mises_kernel>;

class VonMises final : public VonMisesBase {
 public:
  explicit VonMises(const MaterialParams& p) : VonMisesBase(p) {
    using detail::check_value;
    c_.density = density_;
    c_.johnson_cook = p.has("jc_A");
    if (c_.johnson_cook) {
      for (const char* key : {"yield_stress", "hardening"})
        if (p.has(key))
          check_value(p, key, false, "absent when material.jc_A selects Johnson-Cook hardening");
      c_.A = p.get("jc_A");
      c_.B = p.get("jc_B", 0.0);
      c_.n = p.get("jc_n", 1.0);
      c_.C = p.get("jc_C", 0.0);
      c_.m = p.get("jc_m", 1.0);
      check_value(p, "jc_A", c_.A >= 0, ">= 0 (Pa)");
      if (p.has("jc_B")) check_value(p, "jc_B", c_.B >= 0, ">= 0 (Pa)");
      if (p.has("jc_n")) check_value(p, "jc_n", c_.n > 0, "> 0");
      if (p.has("jc_C")) check_value(p, "jc_C", c_.C >= 0, ">= 0");
      if (p.has("jc_m")) check_value(p, "jc_m", c_.m > 0, "> 0");
    } else {
      for (const char* key : {"jc_B", "jc_n", "jc_C", "jc_m", "melt_temperature"})
        if (p.has(key))
          check_value(p, key, false, "absent unless material.jc_A selects Johnson-Cook hardening");
      c_.sigma_y0 = p.get("yield_stress");
      c_.H = p.get("hardening", 0.0);
      check_value(p, "yield_stress", c_.sigma_y0 >= 0, ">= 0 (Pa)");
      if (p.has("hardening")) check_value(p, "hardening", c_.H >= 0, ">= 0 (Pa)");
    }
    c_.rate0 = p.get("reference_strain_rate", 1.0);
    c_.T_room = p.get("room_temperature", 294.0);
    c_.T_melt = p.get("melt_temperature", std::numeric_limits<double>::infinity());
    T0_ = p.get("initial_temperature", c_.T_room);
    c_.specific_heat = p.get("specific_heat", 0.0);
    c_.taylor_quinney = p.get("taylor_quinney", 0.9);
    if (p.has("reference_strain_rate"))
      check_value(p, "reference_strain_rate", c_.rate0 > 0, "> 0 (1/s)");
    if (p.has("room_temperature")) check_value(p, "room_temperature", c_.T_room > 0, "> 0 (K)");
    if (p.has("melt_temperature"))
      check_value(p, "melt_temperature", c_.T_melt > c_.T_room, "above room_temperature (K)");
    if (p.has("initial_temperature")) check_value(p, "initial_temperature", T0_ > 0, "> 0 (K)");
    if (p.has("specific_heat"))
      check_value(p, "specific_heat", c_.specific_heat > 0, "> 0 (J/kg/K)");
    if (p.has("taylor_quinney"))
      check_value(p, "taylor_quinney", c_.taylor_quinney >= 0 && c_.taylor_quinney <= 1,
                  "in [0, 1]");
  }
  std::string name() const override { return "von_mises"; }
  std::vector<std::string> state_names() const override {
    return {"plastic_strain", "temperature", "plastic_strain_rate"};
  }
  void init_state(double* state) const override {
    Material::init_state(state);
    state[1] = T0_;
  }

 private:
  double T0_ = 294.0;
};

}  // namespace

void register_von_mises() {
  detail::add_model<VonMises>("von_mises",
                              {"yield_stress", "hardening", "jc_A", "jc_B", "jc_n", "jc_C", "jc_m",
                               "reference_strain_rate", "room_temperature", "melt_temperature",
                               "initial_temperature", "specific_heat", "taylor_quinney"});
}

}  // namespace gen4d::mpm
