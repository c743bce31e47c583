//! Shared by the blind-case generators of gen4d diagnose (validate_diagnose_library,
//! validate_diagnose_mpm): files written under a temporary name and renamed (an interrupted run
//! leaves no half-written case), noisy marker recordings of a run, and how far two runs' markers
//! lie apart in noise sd.
#pragma once

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "core/Config.hpp"
#include "core/Error.hpp"
#include "diagnose/Forward.hpp"
#include "diagnose/Recording.hpp"

namespace gen4d::driver {

//! Writes `text` to `path` under a temporary name, then renames it.
inline void write_atomic(const std::filesystem::path& path, const std::string& text) {
  const std::filesystem::path tmp = path.string() + ".tmp";
  {
    std::ofstream f(tmp);
    f << text;
    if (!f.flush()) throw RuntimeError("cannot write " + tmp.string());
  }
  std::filesystem::rename(tmp, path);
}

inline std::string json_number(double v) {
  return fmt::format("{:.9g}", v);
}

//! Whether case `name` is generated: --only (`only`) is empty or names it.
inline bool wanted(const std::vector<std::string>& only, const std::string& name) {
  return only.empty() || std::find(only.begin(), only.end(), name) != only.end();
}

//! Throws InputError for a name in --only (`only`) that none of `cases` has.
template <class Case>
void check_only(const std::vector<Case>& cases, const std::vector<std::string>& only) {
  for (const auto& name : only)
    if (std::none_of(cases.begin(), cases.end(), [&](const Case& c) { return c.name == name; }))
      throw InputError(fmt::format("--only: unknown case '{}'", name));
}

//! The members `"k": v, ...` of a JSON object (without the braces).
inline std::string json_members(const std::vector<std::pair<std::string, double>>& kv) {
  std::string s;
  for (const auto& [k, v] : kv)
    s += fmt::format("{}\"{}\": {}", s.empty() ? "" : ", ", k, json_number(v));
  return s;
}

//! The elements `"a", "b", ...` of a JSON array of strings (without the brackets).
inline std::string json_strings(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& e : v) s += fmt::format("{}\"{}\"", s.empty() ? "" : ", ", e);
  return s;
}

//! Sample times k / rate for k = 0 .. end * rate, each jittered by up to 0.2 / rate (uniform,
//! drawn from `rng`), clamped to [0, end] and sorted.
inline std::vector<double> jittered_times(double end, double rate, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  std::vector<double> times;
  for (int k = 0; k <= static_cast<int>(std::lround(end * rate)); ++k)
    times.push_back(std::clamp((k + 0.4 * (uni(rng) - 0.5)) / rate, 0.0, end));
  std::sort(times.begin(), times.end());
  return times;
}

//! The first markers.size() channels of `tr` (positions at `times`) plus Gaussian noise of sd
//! `sd` drawn x, y, z per sample from `seed`; marker ids are their indices.
inline diagnose::Recording noisy_recording(const std::vector<Vec3d>& markers,
                                           const std::vector<double>& times,
                                           const diagnose::Trace& tr, double sd, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, sd);
  diagnose::Recording rec;
  for (std::size_t m = 0; m < markers.size(); ++m) {
    diagnose::Channel ch;
    ch.id = std::to_string(m);
    ch.X = {markers[m][0], markers[m][1], markers[m][2]};
    ch.t = times;
    for (std::size_t k = 0; k < times.size(); ++k)
      ch.value.push_back({tr.channel[m][3 * k] + noise(rng), tr.channel[m][3 * k + 1] + noise(rng),
                          tr.channel[m][3 * k + 2] + noise(rng)});
    rec.channels.push_back(std::move(ch));
  }
  return rec;
}

//! Root mean square difference of the first `markers` channels of two runs (every sample and
//! component), over `sd`.
inline double rms_apart(std::size_t markers, const diagnose::Trace& a, const diagnose::Trace& b,
                        double sd) {
  double d2 = 0;
  std::size_t n = 0;
  for (std::size_t m = 0; m < markers; ++m)
    for (std::size_t k = 0; k < a.channel[m].size(); ++k, ++n)
      d2 += std::pow(a.channel[m][k] - b.channel[m][k], 2);
  return n ? std::sqrt(d2 / static_cast<double>(n)) / sd : 0.0;
}

}  // namespace gen4d::driver
