//! Helpers the effect files share.
#pragma once

#include <vector>

#include "diagnose/Effects.hpp"

namespace gen4d::diagnose::effects {

//! Screening probe groups: each group's probes are combined linearly (Effect::probe_groups).
using Groups = std::vector<std::vector<std::vector<double>>>;

//! How far the calibration must move E (in log) and nu for the effects that absorb into them
//! (contact, a compliant clamp) to be probed on the deck's E and nu as well.
constexpr double kDeckShiftE = 0.15, kDeckShiftNu = 0.05;

//! The calibrated baseline with the deck's nu (and, with_e, the deck's E) in one element,
//! when the calibration moved nu by more than shift_nu (or, with_e, log E by more than
//! shift_e); else none. For effects whose probe is poor where the calibration has absorbed
//! them (Effect::probe_baselines).
std::vector<Physics> deck_baseline(const EffectContext& c, double shift_nu, bool with_e,
                                   double shift_e = 0);

//! An effect whose terms are coefficients of ModelTerms (`fields`, in term order): add_terms sets
//! them, and its absent terms are their null values in ModelTerms.
class CoefficientEffect : public EffectBase {
 public:
  CoefficientEffect(EffectInfo info, std::vector<double ModelTerms::*> fields);
  std::vector<double> absent_terms() const final;
  void add_terms(const std::vector<double>& v, ModelTerms& t) const final;

 private:
  std::vector<double ModelTerms::*> fields_;
};

}  // namespace gen4d::diagnose::effects
