//! Internal to the MPM material models: the explicit registration functions that
//! Registry.cpp calls once, the common base classes (elastic, elastic laws without state,
//! Hencky-elastic return maps), deck-value checks and the small per-particle helpers (Hencky
//! strain, principal stresses, the return's write-back) the model kernels share.
//
// Registration is explicit rather than by static initialisers: the models live in the static
// library gen4d_mpm, and the linker drops object files nobody references, which would silently
// drop self-registering models.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <memory>
#include <utility>
#include <vector>

#include "materials/J2Return.hpp"
#include "materials/Mat3.hpp"
#include "materials/Svd3.hpp"
#include "mpm/Material.hpp"

namespace gen4d::mpm {

// One per model file; Registry.cpp calls each exactly once before the first lookup.
void register_fixed_corotated();
void register_stvk_hencky();
void register_neo_hookean();
void register_drucker_prager();
void register_von_mises();
void register_herschel_bulkley();
void register_fracture();
void register_snow();

namespace detail {

//! Adds an entry without triggering the built-in registration (which calls this itself).
void add_material_entry(MaterialEntry entry);

//! InputError "LOC: material.KEY must be WHAT, got VALUE" unless `ok`.
void check_value(const MaterialParams& params, const std::string& key, bool ok, const char* what);

//! Smallest singular value (stretch) the logarithmic strain and log J use: inverted or
//! collapsed particles get a large but finite restoring stress instead of NaN.
inline constexpr double kMinStretch = 1e-6;

using materials::Mat3;
using materials::Vec3;

inline Mat3 load3x3(const double* a) {
  Mat3 m;
  for (int k = 0; k < 9; ++k) m.a[k] = a[k];
  return m;
}

inline void store3x3(const Mat3& m, double* a) {
  for (int k = 0; k < 9; ++k) a[k] = m.a[k];
}

//! Principal Hencky strain log(sigma) of signed singular values, clamped at kMinStretch.
inline Vec3 hencky_strain(const Vec3& sigma) {
  return Vec3{{std::log(std::max(sigma[0], kMinStretch)), std::log(std::max(sigma[1], kMinStretch)),
               std::log(std::max(sigma[2], kMinStretch))}};
}

inline Vec3 exp3(const Vec3& e) {
  return Vec3{{std::exp(e[0]), std::exp(e[1]), std::exp(e[2])}};
}

inline double trace3(const Vec3& e) {
  return e[0] + e[1] + e[2];
}

inline double norm3(const Vec3& e) {
  return std::sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
}

//! Deviatoric part e - tr(e)/3.
inline Vec3 dev3(const Vec3& e) {
  const double m = trace3(e) / 3.0;
  return Vec3{{e[0] - m, e[1] - m, e[2] - m}};
}

//! Principal Kirchhoff stress of the StVK-Hencky energy mu |e|^2 + lambda/2 tr(e)^2.
inline Vec3 hencky_principal_tau(const Vec3& e, double mu, double lambda) {
  const double l = lambda * trace3(e);
  return Vec3{{2 * mu * e[0] + l, 2 * mu * e[1] + l, 2 * mu * e[2] + l}};
}

//! Symmetric U diag(d) U^T, the Kirchhoff stress of an isotropic model from its principal values.
inline Mat3 from_principal(const Mat3& U, const Vec3& d) {
  return materials::compose_svd(U, d, U);
}

//! Principal Kirchhoff stress of the fixed-corotated energy at signed singular values s:
//! 2 mu (sigma_i - 1) sigma_i + lambda (J - 1) J.
inline Vec3 corotated_principal_tau(const Vec3& s, double mu, double lambda) {
  const double J = s[0] * s[1] * s[2];
  const double vol = lambda * (J - 1) * J;
  return Vec3{{2 * mu * (s[0] - 1) * s[0] + vol, 2 * mu * (s[1] - 1) * s[1] + vol,
               2 * mu * (s[2] - 1) * s[2] + vol}};
}

//! The end of a return in principal Hencky strain e: the elastic F = U exp(e) V^T (skipped when
//! Fp is null: the return left F as it was) and the StVK-Hencky tau = U tau^(e) U^T.
inline void store_hencky_return(const Mat3& U, const Vec3& e, const Mat3& V, double mu,
                                double lambda, double* Fp, double* taup) {
  if (Fp) store3x3(materials::compose_svd(U, exp3(e), V), Fp);
  store3x3(from_principal(U, hencky_principal_tau(e, mu, lambda)), taup);
}

//! fn(i, U, sigma, V) for each of n row-major F's with F_i's signed SVD, computed a block at a
//! time on vector lanes (materials::svd3_batch, the same bits as svd3). fn may change F_i.
template <class Fn>
inline void for_each_svd(std::size_t n, const double* F, const Fn& fn) {
  constexpr std::size_t kBlock = 64;
  double U[9 * kBlock], S[3 * kBlock], V[9 * kBlock];
  for (std::size_t b = 0; b < n; b += kBlock) {
    const std::size_t m = std::min(kBlock, n - b);
    materials::svd3_batch(m, F + 9 * b, U, S, V);
    for (std::size_t k = 0; k < m; ++k)
      fn(b + k, load3x3(U + 9 * k), Vec3{{S[3 * k], S[3 * k + 1], S[3 * k + 2]}},
         load3x3(V + 9 * k));
  }
}

//! StVK-Hencky Kirchhoff stress of n row-major F's: the elastic part shared by the plastic
//! models (their stress() evaluates the current elastic F without a return map).
inline void hencky_stress_batch(std::size_t n, const double* F, double mu, double lambda,
                                double* tau) {
  for_each_svd(n, F, [&](std::size_t i, const Mat3& U, const Vec3& s, const Mat3& V) {
    store_hencky_return(U, hencky_strain(s), V, mu, lambda, nullptr, tau + 9 * i);
  });
}

//! kernel(c, U, sigma, V, F_i, state_i, tau_i, dt) for each of n particles with F_i's signed
//! SVD: the update() of a return-map model with constants c (the kernel writes the projected
//! F_i, its state and tau).
template <class Constants, class Kernel>
inline void for_each_particle(std::size_t n, double* F, double* state, double* tau, double dt,
                              const Constants& c, const Kernel& kernel) {
  for_each_svd(n, F, [&](std::size_t i, const Mat3& U, const Vec3& s, const Mat3& V) {
    kernel(c, U, s, V, F + 9 * i, state + kStateSize * i, tau + 9 * i, dt);
  });
}

//! Root of a strictly decreasing scalar function g on [0, hi] with g(0) > 0 >= g(hi), by Newton
//! steps safeguarded with bisection; `eval(x, g, dg)` gives g(x) and g'(x) (which may be
//! infinite). Stops at |g| <= tol or a bracket at rounding level. While the bracket spans more
//! than three decades the bisection is geometric (the lower end taken as at least 1e-300 hi), so
//! roots far below hi, as with power laws x^n of small n, are found in a few dozen steps.
template <class Eval>
inline double decreasing_root(const Eval& eval, double hi, double x, double tol) {
  double lo = 0;
  for (int it = 0; it < 200; ++it) {
    double g, dg;
    eval(x, g, dg);
    if (std::fabs(g) <= tol) break;
    (g > 0 ? lo : hi) = x;
    if (hi - lo <= 4 * std::numeric_limits<double>::epsilon() * hi) break;
    double next = x - g / dg;
    if (!(next > lo && next < hi))
      next = lo > 1e-3 * hi ? 0.5 * (lo + hi) : std::sqrt(std::max(lo, 1e-300 * hi) * hi);
    x = next;
  }
  return x;
}

}  // namespace detail

//! Base of every model: E, nu, density (validated by make_material) and the Lame parameters.
class ElasticBase : public Material {
 public:
  double wave_speed() const override { return std::sqrt((lambda_ + 2 * mu_) / density_); }

 protected:
  explicit ElasticBase(const MaterialParams& params) {
    E_ = params.get("youngs_modulus");
    nu_ = params.get("poisson_ratio");
    density_ = params.get("density");
    mu_ = E_ / (2 * (1 + nu_));
    lambda_ = E_ * nu_ / ((1 + nu_) * (1 - 2 * nu_));
  }
  double mu_ = 0, lambda_ = 0;
};

//! An elastic model without state: Law gives `static constexpr const char* kName` and
//! `static void stress(n, F, mu, lambda, tau)`; update() leaves F as it is.
template <class Law>
class Hyperelastic final : public ElasticBase {
 public:
  explicit Hyperelastic(const MaterialParams& p) : ElasticBase(p) {}
  std::string name() const override { return Law::kName; }
  std::vector<std::string> state_names() const override { return {}; }
  void update(std::size_t n, double* F, double*, double* tau, double) const override {
    stress(n, F, nullptr, tau);
  }
  void stress(std::size_t n, const double* F, const double*, double* tau) const override {
    Law::stress(n, F, mu_, lambda_, tau);
  }
};

//! Base of the return-map models with StVK-Hencky elasticity (drucker_prager, von_mises,
//! herschel_bulkley): stress() is the elastic stress of the current F, without a return.
class HenckyReturnModel : public ElasticBase {
 public:
  void stress(std::size_t n, const double* F, const double*, double* tau) const override {
    detail::hencky_stress_batch(n, F, mu_, lambda_, tau);
  }

 protected:
  using ElasticBase::ElasticBase;
};

//! A return-map model on Base (ElasticBase or HenckyReturnModel): its constants c_ (the Lame
//! pair set here, the rest by the derived constructor) and update() running Kernel (see
//! detail::for_each_particle) on every particle.
template <class Base, class Constants, auto Kernel>
class ReturnMap : public Base {
 public:
  void update(std::size_t n, double* F, double* state, double* tau, double dt) const override {
    detail::for_each_particle(n, F, state, tau, dt, c_, Kernel);
  }

 protected:
  explicit ReturnMap(const MaterialParams& p) : Base(p) {
    c_.mu = this->mu_;
    c_.lambda = this->lambda_;
  }
  Constants c_{};
};

namespace detail {

//! Files model M (constructed from the deck values) under `name` with its own `keys`.
template <class M>
void add_model(const char* name, std::vector<std::string> keys = {}) {
  add_material_entry(
      {name, std::move(keys), [](const MaterialParams& p) { return std::make_unique<M>(p); }});
}

}  // namespace detail

}  // namespace gen4d::mpm
