//! Constitutive models of the MPM solver (PhysGaussian seed App. B): elastic energies plus
//! return maps that project the trial elastic deformation gradient onto the admissible set.
//
// Adding a model is one .cpp under src/mpm/materials/ defining `void register_<model>()`, declared
// in materials/Models.hpp and called once from materials/Registry.cpp (explicit calls, because a
// static library drops self-registering objects nobody references). The solver calls `update` once
// per batch of particles, so the virtual call is amortised; each model loops over its own inline
// kernel.
#pragma once

#include <cstddef>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace gen4d::mpm {

//! Per-particle plastic / history scalars every model gets (unused ones stay 0).
inline constexpr int kStateSize = 4;

//! Deck values of one material: the model name and its numeric keys (SI units, angles in
//! degrees, temperatures in kelvin). `where` maps a key to "FILE:LINE" for error messages.
struct MaterialParams {
  std::string model;
  std::map<std::string, double> values;
  std::map<std::string, std::string> where;
  std::string source;  //!< deck name, used when a key has no location

  bool has(const std::string& key) const { return values.count(key) != 0; }
  //! Value of a required key; InputError "SOURCE: material.KEY is required for model M".
  double get(const std::string& key) const;
  double get(const std::string& key, double fallback) const;
  //! "FILE:LINE: material.KEY" (or "SOURCE: material.KEY") for messages about `key`.
  std::string locate(const std::string& key) const;
};

class Material {
 public:
  virtual ~Material() = default;
  virtual std::string name() const = 0;
  //! Names of the used state slots, in slot order (at most kStateSize), e.g.
  //! {"plastic_strain", "temperature"}; written to frames and checkpoints.
  virtual std::vector<std::string> state_names() const = 0;
  //! Initial state of a particle (kStateSize values).
  virtual void init_state(double* state) const;
  //! For n particles, row-major 3x3 blocks: F (9n) holds the trial elastic deformation
  //! gradient on entry and the projected (admissible) one on exit; state (kStateSize n) is
  //! updated; tau (9n) receives the Kirchhoff stress tau = P F^T of the projected F.
  //! dt is the substep (rate-dependent models use it).
  virtual void update(std::size_t n, double* F, double* state, double* tau, double dt) const = 0;
  //! Kirchhoff stress of n particles without changing F or state (output, tests).
  virtual void stress(std::size_t n, const double* F, const double* state, double* tau) const = 0;
  //! Upper bound of the elastic P-wave speed sqrt((lambda + 2 mu) / rho), m/s, for the
  //! substep limit.
  virtual double wave_speed() const = 0;
  //! Bound of the P-wave speed of n particles in their current state (kStateSize each) through
  //! the next substep; a model whose stiffness depends on its state (snow's hardening) gives
  //! the bound of the state at hand, others the state-free wave_speed().
  virtual double state_wave_speed(std::size_t n, const double* state) const {
    (void)n;
    (void)state;
    return wave_speed();
  }
  double density() const { return density_; }
  double youngs_modulus() const { return E_; }
  double poisson_ratio() const { return nu_; }

 protected:
  double E_ = 0, nu_ = 0, density_ = 0;
};

struct MaterialEntry {
  std::string name;
  std::vector<std::string> keys;  //!< keys the model accepts besides model/E/nu/density
  std::function<std::unique_ptr<Material>(const MaterialParams&)> build;
};

bool register_material(MaterialEntry entry);
//! Builds the model named params.model; InputError (located) for an unknown model, a key the
//! model does not take, a missing required key, or an out-of-range value.
std::unique_ptr<Material> make_material(const MaterialParams& params);
std::vector<std::string> material_names();
//! Keys model `name` accepts (besides youngs_modulus, poisson_ratio, density).
std::vector<std::string> material_keys(const std::string& name);

}  // namespace gen4d::mpm
