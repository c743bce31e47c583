#include "diagnose/Effects.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "core/Error.hpp"
#include "diagnose/effects/Helpers.hpp"

namespace gen4d::diagnose {

namespace effects {

std::vector<std::unique_ptr<Effect>> builtin_effects();  // effects/Library.cpp

std::vector<Physics> deck_baseline(const EffectContext& c, double shift_nu, bool with_e,
                                   double shift_e) {
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

CoefficientEffect::CoefficientEffect(EffectInfo info, std::vector<double ModelTerms::*> fields)
    : EffectBase(std::move(info)), fields_(std::move(fields)) {}

std::vector<double> CoefficientEffect::absent_terms() const {
  const ModelTerms null;
  std::vector<double> v;
  for (double ModelTerms::*f : fields_) v.push_back(null.*f);
  return v;
}

void CoefficientEffect::add_terms(const std::vector<double>& v, ModelTerms& t) const {
  for (std::size_t i = 0; i < fields_.size(); ++i) t.*fields_[i] = v[i];
}

}  // namespace effects

namespace {

std::vector<std::unique_ptr<Effect>>& library() {
  static std::vector<std::unique_ptr<Effect>> lib = effects::builtin_effects();
  return lib;
}

//! Position of `e` in the library (its size for an effect not in it).
std::size_t library_index(const TermSource* e) {
  const auto& lib = library();
  for (std::size_t i = 0; i < lib.size(); ++i)
    if (lib[i].get() == e) return i;
  return lib.size();
}

}  // namespace

const std::vector<std::unique_ptr<Effect>>& effect_library() {
  return library();
}

void add_effect(std::unique_ptr<Effect> effect) {
  for (const auto& e : library())
    if (e->name() == effect->name())
      throw InputError(fmt::format("an effect called '{}' is already in the library", e->name()));
  library().push_back(std::move(effect));
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

std::vector<double> effect_terms(const Physics& ph, const Effect& effect) {
  for (const auto& a : ph.effects)
    if (a.effect == &effect) return a.terms;
  return effect.absent_terms();
}

void set_effect_terms(Physics& ph, const Effect& effect, std::vector<double> terms) {
  auto& list = ph.effects;
  list.erase(std::remove_if(list.begin(), list.end(),
                            [&](const AppliedEffect& a) { return a.effect == &effect; }),
             list.end());
  // Bitwise, as the memo keys compare them (-0 is not 0 there).
  const std::vector<double> absent = effect.absent_terms();
  if (terms.size() == absent.size() &&
      std::memcmp(terms.data(), absent.data(), sizeof(double) * terms.size()) == 0)
    return;
  const std::size_t at = library_index(&effect);
  auto pos = std::find_if(list.begin(), list.end(),
                          [&](const AppliedEffect& a) { return library_index(a.effect) > at; });
  list.insert(pos, AppliedEffect{&effect, std::move(terms)});
}

void EffectBase::apply(const std::string&, const std::vector<double>& p, const EffectContext&,
                       Physics& ph) const {
  set_effect_terms(ph, *this, p);
}

void set_effect_terms(Physics& ph, const std::string& name, std::vector<double> terms) {
  set_effect_terms(ph, find_effect(name), std::move(terms));
}

}  // namespace gen4d::diagnose
