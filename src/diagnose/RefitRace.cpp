//! Stage refit, the starts of an effect that moves a frequency (continued): starts at the recorded
//! ratio of the two modal frequencies, the race of regions through the continuation windows, and
//! the choice of the start.
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>

#include "core/Log.hpp"
#include "diagnose/RefitWork.hpp"
#include "diagnose/Tuning.hpp"

namespace gen4d::diagnose {

//! With a second mode in the recording, each (region, nu) keeps instead the values where the
//! probes' frequency ratio crosses the recorded one (interpolated in z between grid values, or
//! extrapolated by at most one grid step past the end nearest to it), each probed once more and
//! corrected by a secant step in the effect's parameter and E, so that both modes start in phase.
//! The crossing starts are used when the best of them already removes kRatioStartShare of the
//! calibrated chi-square; else they join the race as lanes of their own.
void ratio_starts(State& s, RefitWork& w, StartSet& S) {
  const std::vector<ParamSpec>& specs = w.specs;
  LsqProblem& pr = w.pr;
  auto& regions = S.regions;
  auto& starts = S.starts;
  auto& start_region = S.start_region;
  auto& matched = S.matched;
  auto& matched_region = S.matched_region;
  if (!s.two_modes) return;
  std::vector<Physics> batch_s;
  std::vector<Crossing> cand;
  std::vector<std::size_t> cand_region;
  std::vector<std::vector<double>> fallback;
  std::vector<std::size_t> fallback_region;
  for (std::size_t k = 0; k < starts.size();) {
    std::size_t k1 = k;
    std::vector<ModePoint> pts;
    while (k1 < starts.size() && start_region[k1] == start_region[k] &&
           starts[k1][1] == starts[k][1]) {
      const ModePoint mp = mode_point(s, S.probe_s[k1], starts[k1][2]);
      if (mp.ok) pts.push_back(mp);
      ++k1;
    }
    const auto crossings = ratio_crossings(pts, s.r_obs);
    // A region whose probes never reach the recorded ratio keeps its grid starts, each matched on
    // omega1.
    if (crossings.empty())
      for (std::size_t q = k; q < k1; ++q) {
        fallback.push_back(starts[q]);
        fallback.back()[0] = match_frequency(s, starts[q][0], S.w_cal, S.probe_s[q]);
        fallback_region.push_back(start_region[q]);
      }
    for (const Crossing& x : crossings) {
      Crossing xc = x;
      xc.z = starts[k];
      xc.z[2] = x.zp;
      xc.z[0] = starts[k][0] + 2 * (std::log(s.modes.omega1) - x.log_w1);
      cand.push_back(xc);
      cand_region.push_back(start_region[k]);
    }
    k = k1;
  }
  for (std::size_t q = 0; q < cand.size(); ++q) {
    s.ctx.region = regions[cand_region[q]];
    batch_s.push_back(pr.physics(cand[q].z));
  }
  const auto probe_m = s.ev->run(batch_s);
  for (std::size_t q = 0; q < cand.size(); ++q) {
    std::vector<double> z = cand[q].z;
    const ModePoint mp = mode_point(s, probe_m[q], z[2]);
    if (mp.ok) secant_correct(s, z, mp, cand[q], pr);
    const BoxRegion& b = regions[cand_region[q]];
    log::info(
        "    ratio start [{:.3g} {:.3g} {:.3g}]-[{:.3g} {:.3g} {:.3g}] "
        "nu {:.3g}: {} {:.4g} "
        "gives ratio {:.4f}, omega1 {:.4g} -> {} {:.4g}, E {:.4g} Pa",
        b.lo[0], b.lo[1], b.lo[2], b.hi[0], b.hi[1], b.hi[2], z[1], specs[0].name,
        from_z(specs[0], cand[q].z[2]), mp.ok ? mp.ratio : 0.0, mp.ok ? std::exp(mp.log_w1) : 0.0,
        specs[0].name, from_z(specs[0], z[2]), std::exp(z[0]));
    matched.push_back(z);
    matched_region.push_back(cand_region[q]);
  }
  // The crossing starts are used when the best of them already removes at least half of the
  // calibrated chi-square: in phase on both s.modes, a start in the true region's basin does, and
  // when none does, the region is not among them and the grid starts race through continuation
  // windows instead.
  if (!matched.empty()) {
    std::vector<Physics> batch_c;
    for (std::size_t q = 0; q < matched.size(); ++q) {
      s.ctx.region = regions[matched_region[q]];
      batch_c.push_back(pr.physics(matched[q]));
    }
    auto runs_c = s.ev->run(batch_c);
    double best_c = 1e300;
    for (const Prediction& p : runs_c)
      if (p.ok) best_c = std::min(best_c, weighted_residual(s.obs, p, s.obs.train).squaredNorm());
    if (!(best_c < kRatioStartShare * s.chi2_0)) {
      log::info(
          "  {} ratio starts: the best fits chi2 {:.4g} of the "
          "calibrated {:.4g} (needs < "
          "{:g}x): the grid starts race instead",
          w.c.effect, best_c, s.chi2_0, kRatioStartShare);
      S.race_crossings = std::move(matched);
      S.race_crossing_region = std::move(matched_region);
      matched.clear();
      matched_region.clear();
    } else {
      S.crossing_runs = std::move(runs_c);
    }
  }
  if (!matched.empty()) {
    log::info(
        "  {} starts: {} ratio crossings of {} grid probes (recorded "
        "ratio {:.4f}), {} grid "
        "starts of regions without one",
        w.c.effect, matched.size(), starts.size(), s.r_obs, fallback.size());
    S.n_crossing = matched.size();
    matched.insert(matched.end(), fallback.begin(), fallback.end());
    matched_region.insert(matched_region.end(), fallback_region.begin(), fallback_region.end());
    starts = matched;
    start_region = matched_region;
  }
}

namespace {

//! Successive halving over lanes (a region and a start each): every lane gets the first window's
//! fit of a continuation fit, and the best `keep` by its chi-square the later windows, scored on
//! the whole recording; the best of those is returned, its region in ri_best. A lane kept follows
//! the path it had in a full race, bit for bit.
LsqResult race(State& s, RefitWork& w, const std::vector<BoxRegion>& regions,
               std::vector<std::size_t> ro, std::vector<std::vector<double>> z_lane,
               std::size_t keep, std::size_t& ri_best) {
  EffectContext& ctx = s.ctx;
  Evaluator& ev = *s.ev;
  const std::vector<double>& windows = s.windows;
  Candidate& c = w.c;
  const std::vector<ParamSpec>& specs = w.specs;
  LsqProblem& pr = w.pr;
  std::vector<double> rest = windows;
  if (!windows.empty() && ro.size() > keep) {
    std::vector<double> chi_w1(ro.size(), 1e300);
    for (std::size_t q = 0; q < ro.size(); ++q) {
      ctx.region = regions[ro[q]];
      const LsqResult rw = window_fit(ev, pr, z_lane[q], windows[0], kWindowIterations);
      if (rw.pred.ok) z_lane[q] = rw.z, chi_w1[q] = rw.chi2;
    }
    std::vector<std::size_t> lanes(ro.size());
    std::iota(lanes.begin(), lanes.end(), 0);
    std::stable_sort(lanes.begin(), lanes.end(),
                     [&](std::size_t a, std::size_t b) { return chi_w1[a] < chi_w1[b]; });
    std::vector<std::size_t> ro_kept;
    std::vector<std::vector<double>> z_kept;
    for (std::size_t k = 0; k < lanes.size(); ++k) {
      const BoxRegion& b = regions[ro[lanes[k]]];
      log::info(
          "  {} race, window t <= {:.3g} s: [{:.3g} {:.3g} "
          "{:.3g}]-[{:.3g} {:.3g} {:.3g}] "
          "E {:.4g} Pa, {} {:.4g}: chi2 {:.4g}{}",
          c.effect, windows[0], b.lo[0], b.lo[1], b.lo[2], b.hi[0], b.hi[1], b.hi[2],
          std::exp(z_lane[lanes[k]][0]), specs[0].name, from_z(specs[0], z_lane[lanes[k]][2]),
          chi_w1[lanes[k]], k < keep ? "" : ": out");
      if (k < keep && chi_w1[lanes[k]] < 1e300)
        ro_kept.push_back(ro[lanes[k]]), z_kept.push_back(z_lane[lanes[k]]);
    }
    ro = ro_kept;
    z_lane = z_kept;
    rest.erase(rest.begin());
  }
  LsqResult best;
  double best_fit = 1e300;
  for (std::size_t q = 0; q < ro.size(); ++q) {
    ctx.region = regions[ro[q]];
    LsqResult rs = continuation_fit(ev, pr, z_lane[q], rest, kWindowIterations, 0, false);
    log::info(
        "  {} short fit in [{:.3g} {:.3g} {:.3g}]-[{:.3g} {:.3g} "
        "{:.3g}]: chi2 {:.4g}, "
        "E {:.4g} Pa, {} {:.4g}",
        c.effect, ctx.region.lo[0], ctx.region.lo[1], ctx.region.lo[2], ctx.region.hi[0],
        ctx.region.hi[1], ctx.region.hi[2], rs.chi2, std::exp(rs.z[0]), specs[0].name,
        from_z(specs[0], rs.z[2]));
    if (rs.pred.ok && rs.chi2 < best_fit) best_fit = rs.chi2, ri_best = ro[q], best = rs;
  }
  return best;
}

}  // namespace

//! The start: every start run (the crossing starts were run for the gate), the best kept, and per
//! region its best. With matched ratios the best start on each side of the effect's null value is a
//! hypothesis (a stiffer region at a lower E and a softer one at a higher E match the same two
//! frequencies), the deck starts' race winner one more. Otherwise, with several regions, the best
//! kRegionStarts regions' starts race (with the turned-away crossings and the deck starts) and the
//! winner is the start.
void pick_start(State& s, RefitWork& w, StartSet& S) {
  const Observations& obs = s.obs;
  EffectContext& ctx = s.ctx;
  Evaluator& ev = *s.ev;
  Candidate& c = w.c;
  const std::vector<ParamSpec>& specs = w.specs;
  LsqProblem& pr = w.pr;
  std::vector<double>& z0 = w.z0;
  const double z_null = w.z_null;
  std::vector<Hypothesis>& hypotheses = w.hypotheses;
  bool& continued = w.continued;
  auto& regions = S.regions;
  auto& located = S.located;
  auto& starts = S.starts;
  auto& start_region = S.start_region;
  auto& probe_s = S.probe_s;
  auto& w_cal = S.w_cal;
  auto& deck_z = S.deck_z;
  auto& deck_region = S.deck_region;
  auto& matched = S.matched;
  auto& n_crossing = S.n_crossing;
  auto& crossing_runs = S.crossing_runs;
  auto& race_crossings = S.race_crossings;
  auto& race_crossing_region = S.race_crossing_region;
  std::vector<Physics> batch_s;
  if (matched.empty())
    for (std::size_t k = 0; k < starts.size(); ++k)
      starts[k][0] = match_frequency(s, starts[k][0], w_cal, probe_s[k]);
  // The crossing starts were run for the gate; the other starts are run here.
  for (std::size_t k = crossing_runs.size(); k < starts.size(); ++k) {
    ctx.region = regions[start_region[k]];
    batch_s.push_back(pr.physics(starts[k]));
  }
  ctx.region = located;
  starts.push_back(z0);
  start_region.push_back(0);
  batch_s.push_back(pr.physics(z0));
  std::vector<Prediction> runs_s = std::move(crossing_runs);
  for (Prediction& p : ev.run(batch_s)) runs_s.push_back(std::move(p));
  double best_chi = 1e300;
  std::size_t best_region = 0;
  // The best start of each region.
  std::vector<double> region_chi(regions.size(), 1e300);
  std::vector<std::vector<double>> region_z(regions.size());
  // With matched ratios: the best start on each side of the effect's null value. Other starts (grid
  // starts of regions without a crossing, the screening start) take a side only by beating every
  // crossing start: a crossing start of the wrong region fits badly, one of a region near the true
  // one is in phase on both modes.
  std::array<double, 2> side_chi = {1e300, 1e300};
  std::array<std::size_t, 2> side_start = {0, 0};
  std::vector<double> chi_s(starts.size(), 1e300);
  double best_crossing = 1e300;
  for (std::size_t k = 0; k < starts.size(); ++k) {
    if (!runs_s[k].ok) continue;
    const double ck = chi_s[k] = weighted_residual(obs, runs_s[k], obs.train).squaredNorm();
    if (ck < best_chi) best_chi = ck, z0 = starts[k], best_region = start_region[k];
    if (ck < region_chi[start_region[k]])
      region_chi[start_region[k]] = ck, region_z[start_region[k]] = starts[k];
    if (k < n_crossing) best_crossing = std::min(best_crossing, ck);
  }
  for (std::size_t k = 0; k < starts.size() && !matched.empty(); ++k) {
    const std::size_t side = starts[k][2] > z_null ? 1 : 0;
    if ((k < n_crossing || chi_s[k] < best_crossing) && chi_s[k] < side_chi[side])
      side_chi[side] = chi_s[k], side_start[side] = k;
  }
  // With both modes in phase at every start, a start's chi-square ranks its basin; but the
  // calibration has absorbed the effect into E and nu, and a stiffer region at a lower E and a
  // softer one at a higher E match the same two frequencies. The best start on each side is a
  // hypothesis; each is fitted briefly and its box refined, and the better one is kept.
  if (!matched.empty() && regions.size() > 1) {
    continued = true;
    for (std::size_t side = 0; side < 2; ++side) {
      if (!(side_chi[side] < 1e299)) continue;
      const std::size_t k = side_start[side];
      Hypothesis h;
      h.region = regions[start_region[k]];
      h.start_chi2 = side_chi[side];
      h.z = starts[k];
      hypotheses.push_back(h);
    }
    // The deck starts: their race's winner, fitted through the windows, is one more.
    if (!deck_z.empty()) {
      std::size_t ri = 0;
      const LsqResult rd = race(s, w, regions, deck_region, deck_z, 1, ri);
      if (rd.pred.ok) {
        Hypothesis h;
        h.region = regions[ri];
        h.start_chi2 = rd.chi2;
        h.z = rd.z;
        hypotheses.push_back(h);
      }
    }
  }
  // With several regions, the best start is not always the best basin: at a start, E and the factor
  // are off the narrow valley they share, and a region near the true one can start worse than a
  // wrong one. The best kRegionStarts regions each get the first window's fit of a continuation
  // fit; the best kRaceKeep of them by its chi-square finish it (the other windows), scored on the
  // whole recording; the best wins and is continued there.
  if (hypotheses.empty() && regions.size() > 1) {
    continued = true;
    std::vector<std::size_t> ro;
    for (std::size_t ri = 0; ri < regions.size(); ++ri)
      if (!region_z[ri].empty()) ro.push_back(ri);
    std::sort(ro.begin(), ro.end(),
              [&](std::size_t a, std::size_t b) { return region_chi[a] < region_chi[b]; });
    ro.resize(std::min(ro.size(), kRegionStarts));
    // The race's lanes: these regions' best starts, the crossing starts the gate turned away and
    // the deck starts; the best kRaceKeep after the first window finish.
    std::vector<std::vector<double>> z_lane;
    for (std::size_t ri : ro) z_lane.push_back(region_z[ri]);
    for (std::size_t q = 0; q < race_crossings.size(); ++q) {
      ro.push_back(race_crossing_region[q]);
      z_lane.push_back(race_crossings[q]);
    }
    for (std::size_t q = 0; q < deck_z.size(); ++q) {
      ro.push_back(deck_region[q]);
      z_lane.push_back(deck_z[q]);
    }
    std::size_t ri = 0;
    const LsqResult rs = race(s, w, regions, ro, z_lane, kRaceKeep, ri);
    if (rs.pred.ok) best_chi = rs.chi2, z0 = rs.z, best_region = ri;
  }
  ctx.region = regions[best_region];
  log::info(
      "  {} start: E {:.4g} Pa, nu {:.3g}, {} {:.4g} (chi2 {:.4g}, best of "
      "{}){}",
      c.effect, std::exp(z0[0]), z0[1], specs[0].name, from_z(specs[0], z0[2]), best_chi,
      starts.size(),
      best_region == 0 ? std::string()
                       : fmt::format(" in [{:.3g} {:.3g} {:.3g}]-[{:.3g} {:.3g} {:.3g}]",
                                     ctx.region.lo[0], ctx.region.lo[1], ctx.region.lo[2],
                                     ctx.region.hi[0], ctx.region.hi[1], ctx.region.hi[2]));
}

}  // namespace gen4d::diagnose
