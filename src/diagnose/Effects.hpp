//! The library of candidate effects `gen4d diagnose` can add to a deck. Each effect is a few
//! parameters that reduce to the deck's physics at their null value, scales and screening
//! probes derived from the scene, the signature it leaves in a recording, and the terms it
//! adds to the forward models (add_terms: coefficients and node forces in a ModelTerms).
//
// Adding an effect: one file effects/<Name>.cpp defining a class derived from EffectBase (or
// effects::CoefficientEffect) and its factory, and one line in the list of effects/Library.cpp.
// Names are what `--effects` and report.json use.
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "diagnose/Forward.hpp"

namespace gen4d::diagnose {

//! Scene scales the effects size their parameters and probes from.
struct EffectContext {
  const ForwardModel* model = nullptr;
  Physics base;             //!< calibrated baseline
  double omega = 1;         //!< dominant angular frequency of the motion, rad/s
  double max_mises = 0;     //!< peak von Mises stress of the baseline run, Pa
  double max_speed = 0;     //!< peak node speed of the baseline run, m/s
  double amplitude = 0;     //!< typical displacement amplitude of the markers, m
  double total_mass = 0;    //!< kg
  double surface_area = 0;  //!< exposed area, m^2
  double lowest_point = 0;  //!< lowest observed marker z, m
  //! The recording's accelerometers' reference points (real sensors have mass).
  std::vector<Vec3d> sensors;
  bool has_region = false;  //!< a region was located by the stiffness sensitivity map
  BoxRegion region;
};

//! One parameter in natural units; the optimiser works on log(value) when `log` is set, else
//! on value / scale. TAO's bounded Newton method is not invariant to a parameter's units: a
//! parameter whose typical values are far from 1 (a clamp's damping, 1e4 Pa s/m) barely moves
//! in its steps, so `scale` should be a typical magnitude.
struct ParamSpec {
  std::string name, unit;
  double lo = 0, hi = 0;  //!< bounds, natural units
  bool log = false;
  double scale = 1;  //!< linear parameters: typical magnitude, natural units
};

class Effect : public TermSource {
 public:
  //! One line: what the effect adds to the model.
  virtual std::string summary() const = 0;
  //! What it does to a recording (amplitude decay, frequency shift, ...).
  virtual std::string signature() const = 0;
  //! Discrete alternatives (material_law: the other laws); default: one unnamed variant.
  virtual std::vector<std::string> variants(const EffectContext&) const { return {""}; }
  //! False when the effect cannot apply to the scene (e.g. heterogeneity without a region).
  virtual bool applicable(const EffectContext&) const { return true; }
  virtual std::vector<ParamSpec> params(const EffectContext& c,
                                        const std::string& variant) const = 0;
  //! Screening probes, natural units: each group's probes are combined linearly.
  virtual std::vector<std::vector<std::vector<double>>> probe_groups(
      const EffectContext& c, const std::string& variant) const = 0;
  //! Baselines besides the calibrated one (EffectContext::base) at which screening probes
  //! the effect as well: each a copy of the calibrated baseline with some of its parameters
  //! changed, run with every probe group applied on top; the best group counts. For effects
  //! whose linear probe is poor where the calibration has carried the baseline, having fitted
  //! the data under the wrong model (material_law: nu at a bound). Default: none.
  virtual std::vector<Physics> probe_baselines(const EffectContext&, const std::string&) const {
    return {};
  }
  //! True when the model response grows from the null value in proportion to the parameters
  //! (so a probe may be scaled to start the fit).
  virtual bool scalable() const { return false; }
  //! Null value of the parameters (the baseline), natural units.
  virtual std::vector<double> null_values(const EffectContext& c,
                                          const std::string& variant) const = 0;
  //! Sets the effect in ph at parameters p (natural units): its term values
  //! (set_effect_terms), or base fields of ph for an effect of the deck's own physics.
  virtual void apply(const std::string& variant, const std::vector<double>& p,
                     const EffectContext& c, Physics& ph) const = 0;
  //! Term values (AppliedEffect::terms) that leave the deck's physics as it is: an entry with
  //! these is dropped from Physics::effects. Empty: any entry changes the physics.
  virtual std::vector<double> absent_terms() const { return {}; }
  //! Free choices beyond the continuous parameters, counted in BIC (region, law).
  virtual int discrete_dof() const { return 0; }
  //! True when the effect makes forward runs several times slower (a return map per Gauss
  //! point): such effects are refitted after the others, so that a passing fit's chi-square
  //! can cut short a fit that cannot compete with it.
  virtual bool slow() const { return false; }
  //! Values of the first parameter (natural units) at which a refit may start, each with E
  //! rescaled to keep the calibrated dominant frequency: for effects that lower (or raise) the
  //! frequency, which the calibration has already absorbed into E, so that any other value at
  //! the calibrated E is out of phase. Empty: start from the screening estimate.
  virtual std::vector<double> frequency_grid(const EffectContext&, const std::string&) const {
    return {};
  }
  //! Regions (besides the located one, EffectContext::region) from which a refit with a
  //! frequency grid also starts, each at the deck's nu: for effects whose region the
  //! linearised stiffness map may miss. Empty: the located region only.
  virtual std::vector<BoxRegion> start_regions(const EffectContext&) const { return {}; }
  //! False for effects diagnose tries only when --effects names them (their verdicts against
  //! the rest of the library are not yet measured on the blind sets).
  virtual bool in_default_library() const { return true; }
};

//! What an effect says of itself.
struct EffectInfo {
  std::string name;       //!< what `--effects` and report.json call it
  std::string summary;    //!< Effect::summary
  std::string signature;  //!< Effect::signature
};

//! The shared form of an effect: its EffectInfo, and by default its parameters as its term
//! values (apply) with the absent terms as their null values.
class EffectBase : public Effect {
 public:
  explicit EffectBase(EffectInfo info) : info_(std::move(info)) {}
  std::string name() const final { return info_.name; }
  std::string summary() const final { return info_.summary; }
  std::string signature() const final { return info_.signature; }
  std::vector<double> null_values(const EffectContext&, const std::string&) const override {
    return absent_terms();
  }
  //! Sets the term values p.
  void apply(const std::string& variant, const std::vector<double>& p, const EffectContext& c,
             Physics& ph) const override;

 private:
  EffectInfo info_;
};

//! Every registered effect, in a fixed order: effects/Library.cpp's list, then any added by
//! add_effect.
const std::vector<std::unique_ptr<Effect>>& effect_library();
//! Appends an effect to the library (a test's own); InputError if its name is taken.
void add_effect(std::unique_ptr<Effect> effect);
//! The term values of `effect` in ph: its entry's, else its absent_terms().
std::vector<double> effect_terms(const Physics& ph, const Effect& effect);
//! Sets the term values of `effect` in ph (in library order; removed at absent_terms()).
void set_effect_terms(Physics& ph, const Effect& effect, std::vector<double> terms);
//! set_effect_terms for the effect called `name`.
void set_effect_terms(Physics& ph, const std::string& name, std::vector<double> terms);
//! The effect called `name`; InputError listing the known names otherwise.
const Effect& find_effect(const std::string& name);
std::vector<std::string> effect_names();

}  // namespace gen4d::diagnose
