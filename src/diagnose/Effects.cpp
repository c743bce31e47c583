#include "diagnose/Effects.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>

#include "core/Error.hpp"

namespace gen4d::diagnose {

namespace {

using Groups = std::vector<std::vector<std::vector<double>>>;

//! Rayleigh damping C = alpha M + beta K.
class Damping final : public Effect {
 public:
  std::string name() const override { return "damping"; }
  std::string summary() const override {
    return "Rayleigh damping C = alpha M + beta K (mass- and stiffness-proportional)";
  }
  std::string signature() const override {
    return "exponential amplitude decay (beta: faster for higher modes)";
  }
  //! mass: C = alpha M; stiffness: C = beta K; rayleigh: both (one mode cannot tell them
  //! apart, so the one-term variants are tried too and BIC picks).
  std::vector<std::string> variants(const EffectContext&) const override {
    return {"mass", "stiffness", "rayleigh"};
  }
  std::vector<ParamSpec> params(const EffectContext& c, const std::string& v) const override {
    const ParamSpec a{"alpha", "1/s", 0.0, c.omega, false},
        b{"beta", "s", 0.0, 1.0 / c.omega, false};
    if (v == "mass") return {a};
    if (v == "stiffness") return {b};
    return {a, b};
  }
  Groups probe_groups(const EffectContext& c, const std::string& v) const override {
    if (v == "mass") return {{{0.04 * c.omega}}};
    if (v == "stiffness") return {{{0.04 / c.omega}}};
    return {{{0.04 * c.omega, 0.0}, {0.0, 0.04 / c.omega}}};
  }
  bool scalable() const override { return true; }
  std::vector<double> null_values(const EffectContext&, const std::string& v) const override {
    return v == "rayleigh" ? std::vector<double>{0, 0} : std::vector<double>{0};
  }
  void apply(const std::string& v, const std::vector<double>& p, const EffectContext&,
             Physics& ph) const override {
    if (v == "mass")
      ph.rayleigh_alpha = p[0];
    else if (v == "stiffness")
      ph.rayleigh_beta = p[0];
    else
      ph.rayleigh_alpha = p[0], ph.rayleigh_beta = p[1];
  }
};

//! Standard linear solid: a fraction g of the stress relaxes with time constant tau.
class Viscoelasticity final : public Effect {
 public:
  std::string name() const override { return "viscoelasticity"; }
  std::string summary() const override {
    return "one-term Prony series (standard linear solid): fraction g relaxes with time tau";
  }
  std::string signature() const override {
    return "frequency-dependent decay with a frequency shift; slow creep under a held load";
  }
  std::vector<ParamSpec> params(const EffectContext& c, const std::string&) const override {
    return {{"g", "", 0.0, 0.9, false}, {"tau", "s", 0.01 / c.omega, 100.0 / c.omega, true}};
  }
  Groups probe_groups(const EffectContext& c, const std::string&) const override {
    return {{{0.05, 0.1 / c.omega}}, {{0.05, 1.0 / c.omega}}, {{0.05, 10.0 / c.omega}}};
  }
  std::vector<double> null_values(const EffectContext& c, const std::string&) const override {
    return {0, 1.0 / c.omega};
  }
  void apply(const std::string&, const std::vector<double>& p, const EffectContext&,
             Physics& ph) const override {
    ph.prony_g = p[0];
    ph.prony_tau = p[1];
  }
};

//! Von Mises plasticity with linear isotropic hardening.
class Plasticity final : public Effect {
 public:
  std::string name() const override { return "plasticity"; }
  bool slow() const override { return true; }
  std::string summary() const override {
    return "von Mises yield with linear isotropic hardening (Hencky elasticity)";
  }
  std::string signature() const override {
    return "permanent set after the load is removed; extra decay while yielding";
  }
  std::vector<ParamSpec> params(const EffectContext& c, const std::string&) const override {
    // Hardening in units of the probes' 0.02 E (in Pa, its steps left it where it started).
    return {{"yield_stress", "Pa", 0.05 * c.max_mises, 2.0 * c.max_mises, true},
            {"hardening", "Pa", 0.0, c.base.youngs_modulus, false, 0.02 * c.base.youngs_modulus}};
  }
  Groups probe_groups(const EffectContext& c, const std::string&) const override {
    const double H = 0.02 * c.base.youngs_modulus;
    return {{{0.4 * c.max_mises, H}}, {{0.6 * c.max_mises, H}}, {{0.8 * c.max_mises, H}}};
  }
  std::vector<double> null_values(const EffectContext& c, const std::string&) const override {
    return {2.0 * c.max_mises, 0};
  }
  void apply(const std::string&, const std::vector<double>& p, const EffectContext& c,
             Physics& ph) const override {
    // At the upper bound nothing yields: keep the elastic law there (the null model).
    if (p[0] < 1.999 * c.max_mises) ph.yield_stress = p[0];
    ph.hardening = p[1];
  }
};

//! How far the calibration must move E (in log) and nu for the effects that absorb into them
//! (contact, a compliant clamp) to be probed on the deck's E and nu as well.
constexpr double kDeckShiftE = 0.15, kDeckShiftNu = 0.05;

//! The calibrated baseline with the deck's nu (and, with_e, the deck's E) in one element,
//! when the calibration moved nu by more than shift_nu (or, with_e, log E by more than
//! shift_e); else none. For effects whose probe is poor where the calibration has absorbed
//! them (Effect::probe_baselines).
std::vector<Physics> deck_baseline(const EffectContext& c, double shift_nu, bool with_e,
                                   double shift_e = 0) {
  if (c.model == nullptr) return {};
  const Physics deck = c.model->nominal();
  const bool nu_moved = std::abs(c.base.poisson_ratio - deck.poisson_ratio) > shift_nu;
  const bool e_moved =
      with_e && std::abs(std::log(c.base.youngs_modulus / deck.youngs_modulus)) > shift_e;
  if (!nu_moved && !e_moved) return {};
  Physics at_deck = c.base;
  at_deck.poisson_ratio = deck.poisson_ratio;
  if (with_e) at_deck.youngs_modulus = deck.youngs_modulus;
  return {at_deck};
}

//! Another hyperelastic law with the same E and nu.
class MaterialLaw final : public Effect {
 public:
  std::string name() const override { return "material_law"; }
  std::string summary() const override {
    return "another hyperelastic law (neo_hookean, stvk, corotated) with the same E, nu";
  }
  std::string signature() const override {
    return "amplitude-dependent stiffness: static offset and frequency change at large strain";
  }
  std::vector<std::string> variants(const EffectContext& c) const override {
    std::vector<std::string> v;
    for (const char* law : {"corotated", "neo_hookean", "stvk"})
      if (c.base.law != law) v.push_back(law);
    return v;
  }
  std::vector<ParamSpec> params(const EffectContext&, const std::string&) const override {
    return {};
  }
  Groups probe_groups(const EffectContext&, const std::string&) const override { return {{{}}}; }
  //! Fitted under the wrong law, nu can run far from the deck's, to a bound (blind
  //! material-law-2: StVK against Neo-Hookean data at 10 % strain, nu 0.45), where another
  //! law is a poor probe (18.7 % of chi2 there, 25.1 % at the deck's nu, which ranks the law
  //! among the effects refitted): when the calibration moved nu by more than
  //! kDeckNuProbeShift, the law is also probed at the deck's nu.
  std::vector<Physics> probe_baselines(const EffectContext& c, const std::string&) const override {
    return deck_baseline(c, kDeckNuProbeShift, false);
  }
  std::vector<double> null_values(const EffectContext&, const std::string&) const override {
    return {};
  }
  void apply(const std::string& variant, const std::vector<double>&, const EffectContext&,
             Physics& ph) const override {
    if (!variant.empty()) ph.law = variant;
  }
  static constexpr double kDeckNuProbeShift = 0.05;
  int discrete_dof() const override { return 1; }
};

//! One region of the body with a different stiffness.
class Heterogeneity final : public Effect {
 public:
  std::string name() const override { return "heterogeneity"; }
  std::string summary() const override {
    return "one box region (located by the stiffness sensitivity map) with E times a factor";
  }
  std::string signature() const override {
    return "mode-shape change and frequency shift; error concentrated near the region";
  }
  bool applicable(const EffectContext& c) const override { return c.has_region; }
  std::vector<ParamSpec> params(const EffectContext&, const std::string&) const override {
    return {{"stiffness_factor", "", 0.05, 20.0, true}};
  }
  Groups probe_groups(const EffectContext&, const std::string&) const override { return {{{0.7}}}; }
  bool scalable() const override { return false; }
  std::vector<double> null_values(const EffectContext&, const std::string&) const override {
    return {1.0};
  }
  void apply(const std::string&, const std::vector<double>& p, const EffectContext& c,
             Physics& ph) const override {
    ph.has_region = true;
    ph.region = c.region;
    ph.region_factor = p[0];
  }
  int discrete_dof() const override { return 6; }
  std::vector<double> frequency_grid(const EffectContext&, const std::string&) const override {
    return {0.2, 0.35, 0.5, 0.7, 1.5, 2.5};  // region stiffness factors
  }
  // The body cut in quarters along its longest axis (snapped to voxels). The map's box is a
  // linearisation at the calibrated state, which has absorbed the region into E and nu: a
  // region stiffer than the rest (E x 2.8 at a cantilever's root) was located at the far side
  // of the calibrated E, with the opposite factor, and the face moves cannot cross from there.
  std::vector<BoxRegion> start_regions(const EffectContext& c) const override {
    const BoxRegion body = c.model->bounds();
    int ax = 0;
    for (int a = 1; a < 3; ++a)
      if (body.hi[a] - body.lo[a] > body.hi[ax] - body.lo[ax]) ax = a;
    const double h = c.model->h(), len = body.hi[ax] - body.lo[ax];
    std::vector<BoxRegion> out;
    for (int q = 0; q < 4; ++q) {
      BoxRegion b = body;
      b.lo[ax] = body.lo[ax] + h * std::round(q * len / (4 * h));
      b.hi[ax] = body.lo[ax] + h * std::round((q + 1) * len / (4 * h));
      if (b.hi[ax] - b.lo[ax] > 0.5 * h) out.push_back(b);
    }
    return out;
  }
};

//! Missing or misdirected gravity / body load.
class Gravity final : public Effect {
 public:
  std::string name() const override { return "gravity"; }
  std::string summary() const override {
    return "body acceleration (gx, gy, gz) other than the deck's gravity";
  }
  std::string signature() const override {
    return "static offset (sag) from the start; oscillation about a shifted mean";
  }
  std::vector<ParamSpec> params(const EffectContext&, const std::string&) const override {
    return {{"gx", "m/s^2", -30, 30, false},
            {"gy", "m/s^2", -30, 30, false},
            {"gz", "m/s^2", -30, 30, false}};
  }
  Groups probe_groups(const EffectContext& c, const std::string&) const override {
    std::vector<std::vector<double>> g(3,
                                       {c.base.gravity[0], c.base.gravity[1], c.base.gravity[2]});
    for (int a = 0; a < 3; ++a) g[static_cast<std::size_t>(a)][static_cast<std::size_t>(a)] += 1.0;
    return {g};
  }
  bool scalable() const override { return true; }
  std::vector<double> null_values(const EffectContext& c, const std::string&) const override {
    return {c.base.gravity[0], c.base.gravity[1], c.base.gravity[2]};
  }
  void apply(const std::string&, const std::vector<double>& p, const EffectContext&,
             Physics& ph) const override {
    ph.gravity = {p[0], p[1], p[2]};
  }
};

//! Elastic (and viscous) support instead of a rigid clamp.
class ClampCompliance final : public Effect {
 public:
  std::string name() const override { return "clamp_compliance"; }
  std::string summary() const override {
    return "the [[fixed]] nodes held by springs and dashpots per unit clamp area";
  }
  std::string signature() const override {
    return "lower frequencies (mostly the first mode), motion at the support, mode-shape change";
  }
  std::vector<ParamSpec> params(const EffectContext& c, const std::string&) const override {
    // Stiffness from compliant (1e-3 E/h) to rigid (1e4 E/h, the null value). Damping up to
    // E/(h omega), a dashpot whose force at the dominant frequency is that of an E/h spring:
    // heavily damped for any clamp compliant enough to be seen (stiffness below ~3 E/h); the
    // optimiser works on it in units of 1 % of that. The bound also sets the fit's
    // finite-difference step (1e-3 of the range): it was 1e4 E/(h omega), a step of 1.8e7
    // Pa s/m on the blind clamp-1, 800 times its true damping of 2.2e4.
    const double k = c.base.youngs_modulus / c.model->h();
    return {{"stiffness", "Pa/m", 1e-3 * k, 1e4 * k, true},
            {"damping", "Pa s/m", 0.0, k / c.omega, false, 1e-2 * k / c.omega}};
  }
  Groups probe_groups(const EffectContext& c, const std::string&) const override {
    const double k = c.base.youngs_modulus / c.model->h();
    return {{{0.1 * k, 0}}, {{1.0 * k, 0}}, {{10.0 * k, 0}}};
  }
  std::vector<double> null_values(const EffectContext& c, const std::string&) const override {
    return {1e4 * c.base.youngs_modulus / c.model->h(), 0};
  }
  //! A compliant clamp lowers the first mode, and the calibration answers with a softer
  //! body: on the blind plate's clamp-1 (first frequency 15 % low) E -33 %, where the clamp
  //! probe screened ninth (9.8 % of chi2) and its dashpots' decay was named stiffness damping.
  //! On the deck's E and nu it screens first (56.5 %), as contact does
  //! (ContactFriction::probe_baselines).
  std::vector<Physics> probe_baselines(const EffectContext& c, const std::string&) const override {
    return deck_baseline(c, kDeckShiftNu, true, kDeckShiftE);
  }
  std::vector<double> frequency_grid(const EffectContext& c, const std::string&) const override {
    const double k = c.base.youngs_modulus / c.model->h();  // clamp stiffness per area, Pa/m
    return {0.03 * k, 0.1 * k, 0.3 * k, 1.0 * k, 3.0 * k};
  }
  void apply(const std::string&, const std::vector<double>& p, const EffectContext& c,
             Physics& ph) const override {
    if (p[0] < 0.999e4 * c.base.youngs_modulus / c.model->h()) {
      ph.clamp_stiffness = p[0];
      ph.clamp_damping = p[1];
    }
  }
};

//! Ground contact with Coulomb friction.
class ContactFriction final : public Effect {
 public:
  std::string name() const override { return "contact_friction"; }
  std::string summary() const override {
    return "a ground plane z = height (normal +z) with Coulomb friction";
  }
  std::string signature() const override {
    return "motion stops or flattens below a level; decay while sliding on the ground";
  }
  std::vector<ParamSpec> params(const EffectContext& c, const std::string&) const override {
    const double a = std::max(c.amplitude, c.model->h());
    return {{"height", "m", c.lowest_point - 3 * a, c.lowest_point + 0.5 * a, false},
            {"friction", "", 0.0, 2.0, false}};
  }
  Groups probe_groups(const EffectContext& c, const std::string&) const override {
    const double a = std::max(c.amplitude, c.model->h());
    return {{{c.lowest_point, 0.3}}, {{c.lowest_point - 0.2 * a, 0.3}}};
  }
  //! A ground the deck leaves out stops the body where a free one would swing on: the
  //! calibration answers with a stiffer body (E up, nu to its bound: on the small blind
  //! cantilever E +34 %, nu 0.3 -> 0.45), which then no longer reaches the recorded lowest
  //! point, so a plane there barely touches it (7.5 % of chi2, twelfth of the screening).
  //! When the calibration moved E by more than kDeckShiftE or nu by more than kDeckShiftNu,
  //! the plane is also probed on the deck's E and nu.
  std::vector<Physics> probe_baselines(const EffectContext& c, const std::string&) const override {
    return deck_baseline(c, kDeckShiftNu, true, kDeckShiftE);
  }
  std::vector<double> null_values(const EffectContext& c, const std::string&) const override {
    return {c.lowest_point - 3 * std::max(c.amplitude, c.model->h()), 0};
  }
  void apply(const std::string&, const std::vector<double>& p, const EffectContext&,
             Physics& ph) const override {
    ph.ground = true;
    ph.ground_height = p[0];
    ph.ground_friction = p[1];
  }
};

//! Aerodynamic drag on the exposed surface.
class AirDrag final : public Effect {
 public:
  std::string name() const override { return "air_drag"; }
  std::string summary() const override {
    return "surface drag per exposed area: -(linear v + quadratic |v| v)";
  }
  std::string signature() const override {
    return "amplitude decay; quadratic part decays faster at large amplitude";
  }
  std::vector<ParamSpec> params(const EffectContext& c, const std::string&) const override {
    const double b1 = unit_linear(c), b2 = b1 / std::max(c.max_speed, 1e-6);
    return {{"linear", "Pa s/m", 0.0, 25.0 * b1, false},
            {"quadratic", "kg/m^3", 0.0, 250.0 * b2, false}};
  }
  Groups probe_groups(const EffectContext& c, const std::string&) const override {
    const double b1 = unit_linear(c), b2 = b1 / std::max(c.max_speed, 1e-6);
    return {{{b1, 0.0}, {0.0, b2}}};
  }
  bool scalable() const override { return true; }
  std::vector<double> null_values(const EffectContext&, const std::string&) const override {
    return {0, 0};
  }
  void apply(const std::string&, const std::vector<double>& p, const EffectContext&,
             Physics& ph) const override {
    ph.drag_linear = p[0];
    ph.drag_quadratic = p[1];
  }

 private:
  //! Linear drag equivalent to a 2 % damping ratio of the body as a whole.
  static double unit_linear(const EffectContext& c) {
    return 0.04 * c.omega * c.total_mass / std::max(c.surface_area, 1e-12);
  }
};

//! Dry friction: a force of constant magnitude opposing the velocity.
class CoulombDamping final : public Effect {
 public:
  std::string name() const override { return "coulomb_damping"; }
  std::string summary() const override {
    return "dry friction: force m a_c opposing each node's velocity";
  }
  std::string signature() const override {
    return "linear (amplitude-independent per cycle) decay, motion stops at a finite time";
  }
  std::vector<ParamSpec> params(const EffectContext& c, const std::string&) const override {
    return {
        {"friction_accel", "m/s^2", 0.0, c.omega * c.omega * std::max(c.amplitude, 1e-9), false}};
  }
  Groups probe_groups(const EffectContext& c, const std::string&) const override {
    return {{{0.02 * c.omega * c.omega * std::max(c.amplitude, 1e-9)}}};
  }
  bool scalable() const override { return true; }
  std::vector<double> null_values(const EffectContext&, const std::string&) const override {
    return {0};
  }
  void apply(const std::string&, const std::vector<double>& p, const EffectContext&,
             Physics& ph) const override {
    ph.coulomb_accel = p[0];
  }
};

}  // namespace

const std::vector<std::unique_ptr<Effect>>& effect_library() {
  static const std::vector<std::unique_ptr<Effect>> lib = [] {
    std::vector<std::unique_ptr<Effect>> l;
    l.push_back(std::make_unique<Damping>());
    l.push_back(std::make_unique<Viscoelasticity>());
    l.push_back(std::make_unique<Plasticity>());
    l.push_back(std::make_unique<MaterialLaw>());
    l.push_back(std::make_unique<Heterogeneity>());
    l.push_back(std::make_unique<Gravity>());
    l.push_back(std::make_unique<ClampCompliance>());
    l.push_back(std::make_unique<ContactFriction>());
    l.push_back(std::make_unique<AirDrag>());
    l.push_back(std::make_unique<CoulombDamping>());
    return l;
  }();
  return lib;
}

std::vector<std::string> effect_names() {
  std::vector<std::string> n;
  for (const auto& e : effect_library()) n.push_back(e->name());
  return n;
}

const Effect& find_effect(const std::string& name) {
  for (const auto& e : effect_library())
    if (e->name() == name) return *e;
  throw InputError(
      fmt::format("unknown effect '{}'; known effects: {}", name, fmt::join(effect_names(), ", ")));
}

}  // namespace gen4d::diagnose
