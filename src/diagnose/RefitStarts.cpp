//! Stage refit, the starts of an effect that moves a frequency (a region's stiffness, a clamp's): a
//! grid of its first parameter with E rescaled to the calibrated frequency, in the located box and
//! the effect's start regions; starts at the deck's E and nu where the calibration moved them far;
//! starts at the recorded ratio of the two modal frequencies; and a race of the regions' best
//! starts through the continuation windows.
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>

#include "core/Log.hpp"
#include "diagnose/RefitWork.hpp"
#include "diagnose/Tuning.hpp"

namespace gen4d::diagnose {

ModePoint mode_point(const State& s, const Prediction& p, double zp) {
  const Observations& obs = s.obs;
  const double t_free = s.t_free;
  const ModalFrequencies& modes = s.modes;
  const bool two_modes = s.two_modes;
  ModePoint m;
  if (!p.ok || !two_modes) return m;
  const ModalFrequencies f =
      modal_frequencies(obs, p.y, t_free, dominant_omega(obs, p.y, t_free), modes.omega2);
  if (!(f.omega2 > 0)) return m;
  m.ok = true;
  m.zp = zp;
  m.ratio = f.omega2 / f.omega1;
  m.log_w1 = std::log(f.omega1);
  return m;
}

void secant_correct(const State& s, std::vector<double>& z, const ModePoint& mp, const Crossing& x,
                    const LsqProblem& pr) {
  const ModalFrequencies& modes = s.modes;
  const double r_obs = s.r_obs;
  double dz = 0;
  if (x.slope_r != 0 && std::isfinite(x.slope_r)) {
    dz = std::clamp((r_obs - mp.ratio) / x.slope_r, -0.5, 0.5);
    const double zn = std::clamp(z[2] + dz, pr.lo[2], pr.hi[2]);
    dz = zn - z[2];
    z[2] = zn;
  }
  z[0] = std::clamp(z[0] + 2 * (std::log(modes.omega1) - mp.log_w1 - x.slope_w * dz), pr.lo[0],
                    pr.hi[0]);
}

namespace {

//! A soft (stiff) region or a compliant clamp changes the frequency, which the calibration has
//! already absorbed into E, and any other value at that E puts the motion out of phase (chi-square
//! has a local minimum per period of phase error). The starts: a grid of values of the effect's
//! first parameter, each later rescaled in E to the calibrated dominant frequency, at the
//! calibrated nu and at the deck's (the calibration bends nu to absorb the effect too), in the
//! located box and in the effect's start_regions() (a region the map may miss; one equal to the
//! located box is not added twice). Their runs are made.
void grid_starts(State& s, RefitWork& w, StartSet& S) {
  const ForwardModel& model = *s.model;
  Diagnosis& D = s.D;
  EffectContext& ctx = s.ctx;
  const std::vector<ParamSpec>& specs = w.specs;
  std::vector<double>& z0 = w.z0;
  auto& regions = S.regions;
  auto& located_is_start = S.located_is_start;
  auto& located = S.located;
  auto& starts = S.starts;
  S.w_cal = dominant_omega(s.obs, s.base.pred.y, s.t_free);
  // A start region that is the located box (to a millionth of a voxel: the two are computed
  // differently) is not added twice; the located box then also starts at the deck's nu, as the
  // start region would have.
  regions = {ctx.region};
  for (const BoxRegion& b : w.e->start_regions(ctx)) {
    bool same = true;
    for (int a = 0; a < 3; ++a)
      same = same && std::abs(b.lo[a] - ctx.region.lo[a]) < 1e-6 * model.h() &&
             std::abs(b.hi[a] - ctx.region.hi[a]) < 1e-6 * model.h();
    if (same)
      located_is_start = true;
    else
      regions.push_back(b);
  }
  located = ctx.region;
  std::vector<Physics> batch_s;
  for (std::size_t ri = 0; ri < regions.size(); ++ri) {
    ctx.region = regions[ri];
    std::vector<double> nus = {ri == 0 ? z0[1] : D.poisson_nominal};
    if (ri == 0 && (std::abs(D.poisson_nominal - z0[1]) > 0.02 ||
                    (located_is_start && D.poisson_nominal != z0[1])))
      nus.push_back(D.poisson_nominal);
    for (double nu : nus)
      for (double f : w.grid) {
        std::vector<double> z = z0;
        z[1] = nu;
        z[2] = to_z(specs[0], std::clamp(f, specs[0].lo, specs[0].hi));
        starts.push_back(z);
        S.start_region.push_back(ri);
        batch_s.push_back(w.pr.physics(z));
      }
  }
  S.probe_s = s.ev->run(batch_s);
}

//! Deck starts. The calibration can take most of a soft (stiff) region into E and nu, far from
//! where the region's basin lies; grid starts at the calibrated E reach that basin only through the
//! factor. When the calibration moved E by more than kDeckStartShiftE (or nu by more than
//! kDeckStartShiftNu), each region also starts at the deck's E and nu, with the factor at which the
//! dominant frequency is the recorded one: the factor grid probed there (or scaled from a grid
//! start's run at the same nu: a linear body's frequencies scale as sqrt(E)), the crossing
//! interpolated, run and moved once more by the secant. These starts race the others.
void deck_starts(State& s, RefitWork& w, StartSet& S) {
  const Observations& obs = s.obs;
  Diagnosis& D = s.D;
  EffectContext& ctx = s.ctx;
  const double t_free = s.t_free;
  const std::vector<ParamSpec>& specs = w.specs;
  LsqProblem& pr = w.pr;
  std::vector<double>& z0 = w.z0;
  const std::vector<double>& grid = w.grid;
  auto& regions = S.regions;
  auto& starts = S.starts;
  auto& deck_region = S.deck_region;
  if (!(regions.size() > 1 && (std::abs(z0[0] - std::log(D.youngs_nominal)) > kDeckStartShiftE ||
                               std::abs(z0[1] - D.poisson_nominal) > kDeckStartShiftNu)))
    return;
  const double lw_obs = std::log(ctx.omega);
  // A probe whose grid start ran at the calibrated E with the deck's nu (every start region's; the
  // S.located box's where it also starts at the deck's nu) is not rerun: a linear body's
  // frequencies scale as sqrt(E) at a fixed factor, nu and density, so its omega is taken from that
  // run, scaled. The crossing found is run anyway (below), so any departure (the load's
  // nonlinearity) costs only the secant's correction. The others (a grid start that failed, at a
  // softer E, or none at the deck's nu) are run.
  std::vector<std::vector<double>> zd;
  std::vector<double> lw_d;  // log omega per (region, factor); NaN: failed
  std::vector<std::size_t> to_run;
  std::vector<char> scaled;  // per (region, factor): omega scaled, not run
  std::vector<Physics> batch_d;
  for (std::size_t ri = 0; ri < regions.size(); ++ri) {
    ctx.region = regions[ri];
    for (double f : grid) {
      std::vector<double> z = z0;
      z[0] = std::clamp(std::log(D.youngs_nominal), pr.lo[0], pr.hi[0]);
      z[1] = D.poisson_nominal;
      z[2] = to_z(specs[0], std::clamp(f, specs[0].lo, specs[0].hi));
      double lw = std::nan("");
      for (std::size_t k = 0; k < starts.size() && std::isnan(lw); ++k)
        if (S.start_region[k] == ri && starts[k][1] == z[1] && starts[k][2] == z[2] &&
            S.probe_s[k].ok)
          lw = std::log(dominant_omega(obs, S.probe_s[k].y, t_free)) + 0.5 * (z[0] - starts[k][0]);
      if (std::isnan(lw)) {
        to_run.push_back(zd.size());
        batch_d.push_back(pr.physics(z));
      }
      scaled.push_back(!std::isnan(lw));
      zd.push_back(z);
      lw_d.push_back(lw);
    }
  }
  {
    const auto probe_d = s.ev->run(batch_d);
    for (std::size_t q = 0; q < to_run.size(); ++q)
      if (probe_d[q].ok) lw_d[to_run[q]] = std::log(dominant_omega(obs, probe_d[q].y, t_free));
  }
  batch_d.clear();
  // Per region, where log omega (piecewise linear in the grid's z) crosses the recorded one:
  // ratio_crossings on points whose "ratio" is log omega (interpolated, or with no crossing
  // extrapolated at most one grid step: the grid's soft end can fail under the load).
  struct DeckCross {
    std::vector<double> z;
    double slope = 0;  // d log omega / d z there
  };
  std::vector<DeckCross> cross;
  const std::size_t ng = grid.size();
  for (std::size_t ri = 0; ri < regions.size(); ++ri) {
    std::vector<ModePoint> pts;
    std::string line;
    for (std::size_t g = 0; g < ng; ++g) {
      const std::size_t i = ri * ng + g;
      if (std::isnan(lw_d[i])) continue;
      ModePoint mp;
      mp.ok = true;
      mp.zp = zd[i][2];
      mp.ratio = mp.log_w1 = lw_d[i];
      pts.push_back(mp);
      line += fmt::format(" {:.3g}: {:.4g}{}", from_z(specs[0], mp.zp), std::exp(mp.ratio),
                          scaled[i] ? "s" : "");
    }
    log::info(
        "    deck probes [{:.3g} {:.3g} {:.3g}]-[{:.3g} {:.3g} {:.3g}], "
        "omega at {}{} (s: "
        "scaled from the calibrated E's run)",
        regions[ri].lo[0], regions[ri].lo[1], regions[ri].lo[2], regions[ri].hi[0],
        regions[ri].hi[1], regions[ri].hi[2], specs[0].name, line);
    for (const Crossing& x : ratio_crossings(pts, lw_obs)) {
      DeckCross d;
      d.z = zd[ri * ng];
      d.z[2] = std::clamp(x.zp, pr.lo[2], pr.hi[2]);
      d.slope = x.slope_r;
      cross.push_back(d);
      deck_region.push_back(ri);
    }
  }
  for (std::size_t q = 0; q < cross.size(); ++q) {
    ctx.region = regions[deck_region[q]];
    batch_d.push_back(pr.physics(cross[q].z));
  }
  const auto probe_x = s.ev->run(batch_d);
  std::vector<std::size_t> kept_region;
  for (std::size_t q = 0; q < cross.size(); ++q) {
    std::vector<double> z = cross[q].z;
    double w = 0;
    if (probe_x[q].ok) w = dominant_omega(obs, probe_x[q].y, t_free);
    // A start whose run misses the recorded frequency by more than kDeckStartReach (an
    // extrapolation past a grid end that does not get there, or a failed run) is dropped: at the
    // deck's E no factor of that region matches the recording.
    const bool near = w > 0 && std::abs(std::log(w) - lw_obs) < kDeckStartReach;
    if (near && cross[q].slope != 0) {
      const double dz = std::clamp((lw_obs - std::log(w)) / cross[q].slope, -0.25, 0.25);
      z[2] = std::clamp(z[2] + dz, pr.lo[2], pr.hi[2]);
    }
    const BoxRegion& b = regions[deck_region[q]];
    log::info(
        "    deck start [{:.3g} {:.3g} {:.3g}]-[{:.3g} {:.3g} {:.3g}] at "
        "E {:.4g} Pa, nu "
        "{:.3g}: {} {:.4g} gives omega {:.4g} rad/s (recorded {:.4g}){}",
        b.lo[0], b.lo[1], b.lo[2], b.hi[0], b.hi[1], b.hi[2], std::exp(z[0]), z[1], specs[0].name,
        from_z(specs[0], cross[q].z[2]), w, ctx.omega,
        near ? fmt::format(" -> {} {:.4g}", specs[0].name, from_z(specs[0], z[2]))
             : std::string(": dropped"));
    if (!near) continue;
    S.deck_z.push_back(z);
    kept_region.push_back(deck_region[q]);
  }
  deck_region = kept_region;
  log::info(
      "  {} deck starts (the calibration moved E {:+.0f} %, nu {:+.3f}): "
      "{} of {} regions",
      w.c.effect, 100 * (std::exp(z0[0]) / D.youngs_nominal - 1), z0[1] - D.poisson_nominal,
      S.deck_z.size(), regions.size());
  ctx.region = S.located;
}

}  // namespace

void frequency_starts(State& s, RefitWork& w) {
  StartSet S;
  grid_starts(s, w, S);
  deck_starts(s, w, S);
  ratio_starts(s, w, S);
  pick_start(s, w, S);
}

}  // namespace gen4d::diagnose
