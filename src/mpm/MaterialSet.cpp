#include "mpm/MaterialSet.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <stdexcept>

#include "core/ParallelFor.hpp"

namespace gen4d::mpm {

MaterialSet::MaterialSet(std::shared_ptr<const Material> only) {
  slots_.push_back(std::move(only));
}

MaterialSet::MaterialSet(std::vector<std::shared_ptr<const Material>> slots)
    : slots_(std::move(slots)) {
  if (slots_.empty() || slots_.size() > 256)
    throw std::logic_error(fmt::format("MaterialSet: {} materials (1 to 256)", slots_.size()));
}

double MaterialSet::wave_speed() const {
  double c = 0;
  for (const auto& m : slots_) c = std::max(c, m->wave_speed());
  return c;
}

std::vector<std::string> MaterialSet::state_names() const {
  std::size_t width = 0;
  for (const auto& m : slots_) width = std::max(width, m->state_names().size());
  std::vector<std::string> out(width);
  for (std::size_t k = 0; k < width; ++k) {
    std::vector<std::string> names;
    for (const auto& m : slots_) {
      const auto own = m->state_names();
      names.push_back(k < own.size() ? own[k] : "");
    }
    const bool same = std::all_of(names.begin(), names.end(),
                                  [&](const std::string& s) { return s == names[0]; });
    out[k] = same ? names[0] : fmt::format("{}", fmt::join(names, "|"));
  }
  return out;
}

std::string MaterialSet::describe() const {
  std::vector<std::string> names;
  for (const auto& m : slots_) names.push_back(m->name());
  return fmt::format("{}", fmt::join(names, " + "));
}

template <class Fn>
void MaterialSet::for_runs(std::size_t n, const std::uint8_t* slot, Fn&& fn) const {
  std::size_t begin = 0;
  while (begin < n) {
    std::size_t end = begin + 1;
    while (end < n && slot[end] == slot[begin]) ++end;
    if (slot[begin] >= slots_.size())
      throw std::logic_error(
          fmt::format("MaterialSet: particle material slot {} of {}", slot[begin], slots_.size()));
    fn(*slots_[slot[begin]], begin, end - begin);
    begin = end;
  }
}

void MaterialSet::update(std::size_t n, const std::uint8_t* slot, double* F, double* state,
                         double* tau, double dt) const {
  // Each run in blocks, one per host thread (the models' update is const and per particle).
  for_runs(n, slot, [&](const Material& m, std::size_t i, std::size_t count) {
    exec::parallel_blocks(static_cast<long>(count), [&](long b, long e) {
      const std::size_t j = i + static_cast<std::size_t>(b);
      m.update(static_cast<std::size_t>(e - b), F + 9 * j, state + kStateSize * j, tau + 9 * j, dt);
    });
  });
}

double MaterialSet::state_wave_speed(std::size_t n, const std::uint8_t* slot,
                                     const double* state) const {
  double c = 0;
  for_runs(n, slot, [&](const Material& m, std::size_t i, std::size_t count) {
    c = std::max(c, m.state_wave_speed(count, state + kStateSize * i));
  });
  return c;
}

void MaterialSet::stress(std::size_t n, const std::uint8_t* slot, const double* F,
                         const double* state, double* tau) const {
  for_runs(n, slot, [&](const Material& m, std::size_t i, std::size_t count) {
    exec::parallel_blocks(static_cast<long>(count), [&](long b, long e) {
      const std::size_t j = i + static_cast<std::size_t>(b);
      m.stress(static_cast<std::size_t>(e - b), F + 9 * j, state + kStateSize * j, tau + 9 * j);
    });
  });
}

}  // namespace gen4d::mpm
