//! The profile of the selected fit's effect parameters (stage check): points at given values with
//! the other parameters re-optimised, the probes, their refinement near the threshold and the
//! crossings read off them.
#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "core/Log.hpp"
#include "diagnose/Profile.hpp"
#include "diagnose/Tuning.hpp"

namespace gen4d::diagnose {

//! A run's chi-square above the fit's, in units of s2 (a failed run: far beyond any).
double dchi_of(const State& s, const Profile& P, const Prediction& p) {
  const Observations& obs = s.obs;
  const Candidate* best = s.best;
  const double s2 = P.s2;
  return p.ok ? (weighted_residual(obs, p, obs.train).squaredNorm() - best->chi2) / s2 : 1e300;
}

namespace {

//! The profile at given values of the effect's parameters ((q, z_q) each): the others first at the
//! linearised conditional optimum, then re-optimised; each point's chi-square above the fit in
//! units of s2 (1e300 where its run failed). The points' runs go in batches. Along a curved ridge
//! the linearised point sits off the ridge and overstates the profile: Gauss-Newton steps of the
//! others from the point (each one run per point; the first with the fit's Jacobian, each next with
//! Broyden's update, held within the bounds) move it onto the ridge. A point stops at a step that
//! does not lower its chi-square by kProfileGain of the threshold, or after kProfileSteps; its
//! lowest chi-square is the profile's.
std::vector<double> profile_at(State& s, Profile& P,
                               const std::vector<std::pair<std::size_t, double>>& at) {
  const Observations& obs = s.obs;
  Evaluator& ev = *s.ev;
  const Candidate* best = s.best;
  const std::vector<ParamSpec>& specs = P.specs;
  const LsqProblem& pr = P.pr;
  const std::size_t np = P.np;
  const auto& phys = P.pr.physics;
  const Eigen::MatrixXd& J = P.J;
  const double thr = P.thr;
  IntervalBasis& IB = s.D.intervals;
  const auto& others = P.others;
  const auto& others_J = P.others_J;
  const auto& others_qr = P.others_qr;
  std::vector<Physics> ends;
  std::vector<std::vector<double>> zends;
  for (const auto& [q, zq] : at) {
    const std::size_t j = 2 + q;
    const auto& oth = others[q];
    std::vector<double> z = best->z;
    const Eigen::VectorXd shift =
        others_qr[q].solve(-J.col(static_cast<Eigen::Index>(j)) * (zq - P.best_z[j]));
    for (std::size_t o = 0; o < oth.size(); ++o)
      z[oth[o]] =
          std::clamp(z[oth[o]] + shift[static_cast<Eigen::Index>(o)], pr.lo[oth[o]], pr.hi[oth[o]]);
    z[j] = zq;
    zends.push_back(z);
    ends.push_back(phys(z));
  }
  const auto ep = ev.run(ends);
  std::vector<double> dchi(at.size());
  struct Walk {
    std::size_t idx;
    std::vector<double> z;
    Eigen::VectorXd r;
    Eigen::MatrixXd Jo;
  };
  std::vector<Walk> walks;
  for (std::size_t idx = 0; idx < at.size(); ++idx) {
    dchi[idx] = dchi_of(s, P, ep[idx]);
    const std::size_t q = at[idx].first;
    if (!ep[idx].ok || at[idx].second == P.best_z[2 + q] || np < 2) continue;
    walks.push_back(Walk{idx, zends[idx], weighted_residual(obs, ep[idx], obs.train), others_J[q]});
  }
  for (int step = 0; step < kProfileSteps && !walks.empty(); ++step) {
    std::vector<Physics> corr;
    std::vector<std::vector<double>> zc;
    std::vector<Walk*> of;
    for (auto& w : walks) {
      const auto& oth = others[at[w.idx].first];
      std::vector<double> zo, lo, hi;
      for (std::size_t k : oth)
        zo.push_back(w.z[k]), lo.push_back(pr.lo[k]), hi.push_back(pr.hi[k]);
      const Eigen::VectorXd shift = bounded_gauss_newton_step(w.Jo, w.r, zo, lo, hi);
      std::vector<double> z = w.z;
      bool moved = false;
      for (std::size_t o = 0; o < oth.size(); ++o) {
        const std::size_t k = oth[o];
        const double zk =
            std::clamp(z[k] + shift[static_cast<Eigen::Index>(o)], pr.lo[k], pr.hi[k]);
        moved = moved || std::abs(zk - z[k]) > 1e-3 * std::abs(pr.step[k]);
        z[k] = zk;
      }
      if (!moved) continue;
      corr.push_back(phys(z));
      zc.push_back(std::move(z));
      of.push_back(&w);
    }
    const auto cp = ev.run(corr);
    IB.profile_runs += static_cast<long>(corr.size());
    std::vector<Walk> next;
    for (std::size_t k = 0; k < corr.size(); ++k) {
      Walk& w = *of[k];
      const std::size_t idx = w.idx, q = at[idx].first;
      const double d = dchi_of(s, P, cp[k]);
      if (!(d < dchi[idx])) continue;
      ++IB.profile_lowered;
      log::info(
          "  profile: {} at {:.5g}, step {}: the others re-optimised "
          "lower chi2 by {:.3g} s2 "
          "({:.3g} -> {:.3g})",
          specs[q].name, from_z(specs[q], at[idx].second), step + 1, dchi[idx] - d, dchi[idx], d);
      const bool go_on = dchi[idx] - d > kProfileGain * thr;
      dchi[idx] = d;
      if (!go_on) continue;
      // Broyden's update of the others' Jacobian: Jo s = the residual's change.
      const auto& oth = others[q];
      Eigen::VectorXd sv(static_cast<Eigen::Index>(oth.size()));
      for (std::size_t o = 0; o < oth.size(); ++o)
        sv[static_cast<Eigen::Index>(o)] = zc[k][oth[o]] - w.z[oth[o]];
      const Eigen::VectorXd rn = weighted_residual(obs, cp[k], obs.train);
      w.Jo += ((rn - w.r) - w.Jo * sv) * (sv.transpose() / sv.squaredNorm());
      w.r = rn;
      w.z = zc[k];
      next.push_back(std::move(w));
    }
    walks = std::move(next);
  }
  return dchi;
}

//! A point of end idx's profile, kept in order of distance from the fit.
void add_point(Profile& P, std::size_t idx, double zv, double dchi) {
  auto& sides = P.sides;
  const auto& at = P.at;
  const double z0 = P.best_z[2 + at[idx].first];
  auto& pts = sides[idx].pts;
  const auto pos =
      std::upper_bound(pts.begin(), pts.end(), std::abs(zv - z0),
                       [&](double dist, const auto& pt) { return dist < std::abs(pt.first - z0); });
  pts.emplace(pos, zv, dchi);
  sides[idx].last = dchi;
}

}  // namespace

//! Where the profile crosses a threshold T on an end's side: between the nearest point at or above
//! T and the point before it, linear in the square root of chi-square (exact for a quadratic
//! profile). With no point at or above T, the quadratic through the fit and the farthest point,
//! extrapolated at most `max_reach` times its distance (the interval reaches at least that point,
//! and its bound where the point sits on it).
double crossing(const Profile& P, std::size_t idx, double T, double max_reach, bool& at_bound) {
  const LsqProblem& pr = P.pr;
  auto& sides = P.sides;
  const auto& at = P.at;
  const std::size_t j = 2 + at[idx].first;
  const auto& pts = sides[idx].pts;
  const double z0 = P.best_z[j];
  at_bound = false;
  auto root = [](double d) { return std::sqrt(std::max(d, 0.0)); };
  for (std::size_t k = 1; k < pts.size(); ++k)
    if (pts[k].second >= T) {
      const auto& in = pts[k - 1];
      const auto& out = pts[k];
      const double f = (root(T) - root(in.second)) / (root(out.second) - root(in.second));
      return in.first + (out.first - in.first) * std::clamp(f, 0.0, 1.0);
    }
  const auto& far = pts.back();
  const double dz = far.first - z0;
  if (dz == 0) {
    at_bound = true;
    return z0;
  }
  at_bound = far.first <= pr.lo[j] || far.first >= pr.hi[j];
  return at_bound ? far.first
                  : z0 + dz * std::min(max_reach, std::sqrt(T / std::max(far.second, 1e-12)));
}

//! The probes: two per effect parameter (index 2 q + side), sqrt(thr) (or 2) conditional standard
//! errors out; an unconstrained parameter (a zero Jacobian column) has an infinite standard error
//! and its probes go to the bounds. Their profile points.
void probes(State& s, Profile& P) {
  const std::vector<ParamSpec>& specs = P.specs;
  const LsqProblem& pr = P.pr;
  const Eigen::MatrixXd& J = P.J;
  const double s2 = P.s2;
  auto& at = P.at;
  for (std::size_t q = 0; q < specs.size(); ++q) {
    const std::size_t j = 2 + q;
    // An unconstrained parameter (a zero Jacobian column: hardening when almost nothing yields) has
    // an infinite standard error: its probes go to the bounds, and its interval is the range (the
    // pseudo-inverse's zero variance gave an interval of zero width).
    const double se = std::min(conditional_standard_error(J, static_cast<Eigen::Index>(j), s2),
                               2 * (pr.hi[j] - pr.lo[j]) + 1.0);
    for (int side = -1; side <= 1; side += 2)
      at.emplace_back(q, std::clamp(P.best_z[j] + side * P.probe * se, pr.lo[j], pr.hi[j]));
  }
  P.sides.resize(at.size());
  {
    const std::vector<double> d = profile_at(s, P, at);
    for (std::size_t idx = 0; idx < at.size(); ++idx) {
      add_point(P, idx, P.best_z[2 + at[idx].first], 0.0);
      add_point(P, idx, at[idx].second, d[idx]);
    }
  }
}

//! A probe placed by the linearisation can land far from the crossing, where the crossing read off
//! it is misplaced. The profile is then probed again where `crossing` puts the end, while the
//! points bracketing it are more than a factor 2 from the threshold (the inner below T/2, the outer
//! above 2 T) or, with none above it, the farthest lies below T/2 and off the bound (halfway to a
//! failed run, or where the last probe fell inside again: bisection): kProfileRefines times at
//! most, every end's probes in one batch.
void refine_probes(State& s, Profile& P) {
  const std::vector<ParamSpec>& specs = P.specs;
  const LsqProblem& pr = P.pr;
  const double thr = P.thr;
  const double reach = P.reach;
  IntervalBasis& IB = s.D.intervals;
  auto& sides = P.sides;
  const auto& at = P.at;
  for (int round = 0; round < kProfileRefines; ++round) {
    std::vector<std::pair<std::size_t, double>> again;
    std::vector<std::size_t> again_of;
    for (std::size_t idx = 0; idx < at.size(); ++idx) {
      const std::size_t j = 2 + at[idx].first;
      const auto& pts = sides[idx].pts;
      const double z0 = P.best_z[j];
      if (pts.back().first == z0) continue;
      bool wide_bracket = false;
      std::size_t k = 1;
      while (k < pts.size() && pts[k].second < thr) ++k;
      if (k < pts.size())
        wide_bracket = pts[k].second > 2 * thr && pts[k - 1].second < 0.5 * thr;
      else
        wide_bracket = pts.back().second < 0.5 * thr && pts.back().first > pr.lo[j] &&
                       pts.back().first < pr.hi[j];
      if (!wide_bracket) continue;
      bool nb = false;
      // Halfway into the bracket where its outer point's run failed, or where the last probe again
      // fell inside (the profile flat, then a cliff: the square root's interpolation keeps landing
      // next to the inner point); else where `crossing` reads the end.
      const bool last_inside = pts.size() > 2 && sides[idx].last < thr;
      const double target = k < pts.size() && (!(pts[k].second < 1e299) || last_inside)
                                ? 0.5 * (pts[k - 1].first + pts[k].first)
                                : std::clamp(crossing(P, idx, thr, reach, nb), pr.lo[j], pr.hi[j]);
      bool known = false;
      for (const auto& pt : pts)
        known = known || std::abs(pt.first - target) <= 1e-3 * std::abs(pts.back().first - z0);
      if (known) continue;
      again.emplace_back(at[idx].first, target);
      again_of.push_back(idx);
    }
    if (again.empty()) break;
    const std::vector<double> d2 = profile_at(s, P, again);
    IB.profile_refines += static_cast<long>(again.size());
    for (std::size_t k = 0; k < again.size(); ++k) {
      const std::size_t idx = again_of[k], q = at[idx].first;
      log::info(
          "  profile: {} probed again at {:.5g}: chi2 {:.3g} s2 above the fit "
          "(threshold {:.3g})",
          specs[q].name, from_z(specs[q], again[k].second), d2[k], thr);
      add_point(P, idx, again[k].second, d2[k]);
    }
  }
}

}  // namespace gen4d::diagnose
