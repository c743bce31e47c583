//! Stage refit, a heterogeneity box refined by forward runs: each face moved in or out by one
//! voxel, or out to the body's bound (a greedy voxel step cannot cross a worse half-way box); the
//! best move kept while it lowers chi-square by more than 0.5 %, then refitted.
#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>

#include "core/Log.hpp"
#include "diagnose/RefitWork.hpp"
#include "diagnose/Tuning.hpp"

namespace gen4d::diagnose {

namespace {

//! The moves of a round: each box with its start (z), the box they move from, and per move its best
//! chi-square so far and the run there.
struct Moves {
  std::vector<std::pair<BoxRegion, std::vector<double>>> tries;
  BoxRegion keep;
  std::vector<std::size_t> all;  //!< 0 .. tries.size() - 1
  bool secant = false;           //!< moves put back onto both modal frequencies
  std::vector<double> chi_matched;
  std::vector<Prediction> pred_try;
};

//! The boxes one face move away from the current region (ctx.region), within the body.
std::vector<BoxRegion> face_moves(const State& s) {
  const Diagnosis& D = s.D;
  const EffectContext& ctx = s.ctx;
  const double h = s.model->h();
  std::vector<BoxRegion> boxes;
  for (int a = 0; a < 3; ++a)
    for (int side = 0; side < 2; ++side)
      for (int dir = -1; dir <= 2; ++dir) {  // in, out by one voxel; 2: out to the body
        if (dir == 0) continue;
        BoxRegion b = ctx.region;
        if (dir == 2)
          (side ? b.hi : b.lo)[a] = (side ? D.body.hi : D.body.lo)[a];
        else
          (side ? b.hi : b.lo)[a] += dir * h;
        b.lo[a] = std::max(b.lo[a], D.body.lo[a]);
        b.hi[a] = std::min(b.hi[a], D.body.hi[a]);
        if (b.hi[a] - b.lo[a] < 0.5 * h) continue;
        if (std::abs(b.lo[a] - ctx.region.lo[a]) < 1e-12 * h &&
            std::abs(b.hi[a] - ctx.region.hi[a]) < 1e-12 * h)
          continue;
        bool seen = false;
        for (const BoxRegion& o : boxes) seen = seen || (o.lo == b.lo && o.hi == b.hi);
        if (!seen) boxes.push_back(b);
      }
  return boxes;
}

//! The moves to `boxes`, each at the factor f' that keeps the region's added compliance (1/f - 1) V
//! (moving a face is a question of shape: at a fixed factor a larger box is simply a softer body);
//! E is matched to the current fit's frequency afterwards (match_moves).
Moves make_moves(State& s, RefitWork& w, const LsqResult& r, const std::vector<BoxRegion>& boxes) {
  EffectContext& ctx = s.ctx;
  const bool two_modes = s.two_modes;
  const std::vector<ParamSpec>& specs = w.specs;
  std::vector<Hypothesis>& hypotheses = w.hypotheses;
  Moves M;
  auto& tries = M.tries;
  M.keep = ctx.region;
  auto volume = [](const BoxRegion& b) {
    return (b.hi[0] - b.lo[0]) * (b.hi[1] - b.lo[1]) * (b.hi[2] - b.lo[2]);
  };
  const double f = from_z(specs[0], r.z[2]);
  for (const BoxRegion& b : boxes) {
    const double inv = 1 + (1 / f - 1) * volume(M.keep) / volume(b);
    if (!(inv > 0)) continue;
    std::vector<double> z = r.z;
    z[2] = to_z(specs[0], std::clamp(1 / inv, specs[0].lo, specs[0].hi));
    tries.push_back({b, z});
  }
  M.all.resize(tries.size());
  for (std::size_t i = 0; i < tries.size(); ++i) M.all[i] = i;
  M.secant = two_modes && !hypotheses.empty();
  return M;
}

//! The runs of the moves `which` (each in its own box).
std::vector<Prediction> run_tries(State& s, RefitWork& w, const Moves& M,
                                  const std::vector<std::size_t>& which) {
  EffectContext& ctx = s.ctx;
  Evaluator& ev = *s.ev;
  LsqProblem& pr = w.pr;
  auto& tries = M.tries;
  const BoxRegion& keep = M.keep;
  std::vector<Physics> batch_b;
  for (std::size_t i : which) {
    ctx.region = tries[i].first;
    batch_b.push_back(pr.physics(tries[i].second));
  }
  ctx.region = keep;
  return ev.run(batch_b);
}

//! Each move's E rescaled so that the dominant frequency stays the current fit's (else the phase
//! error hides a better shape): from the two boxes' rest frequencies (no run), or from a run of the
//! move's motion. With two modes recorded (secant), each move is put back onto both frequencies by
//! a second probe's slopes. Returns the moves' runs at the matched points.
std::vector<Prediction> match_moves(State& s, RefitWork& w, const LsqResult& r, Moves& M,
                                    double w_fit) {
  const Observations& obs = s.obs;
  const ForwardModel& model = *s.model;
  EffectContext& ctx = s.ctx;
  Evaluator& ev = *s.ev;
  const double t_free = s.t_free;
  const ModalFrequencies& modes = s.modes;
  const double r_obs = s.r_obs;
  LsqProblem& pr = w.pr;
  const double z_null = w.z_null;
  auto& tries = M.tries;
  const BoxRegion& keep = M.keep;
  const std::vector<std::size_t>& all = M.all;
  const bool secant = M.secant;
  // Without the secant below, a move's E follows from rest frequencies (no run: the ratio of the
  // current box's to the move's at the same E).
  std::vector<Prediction> probe_b;
  bool rest_matched = false;
  if (!secant) {
    const Vec3d dir = motion_direction(obs, t_free);
    const double w_cur = model.rest_frequency(pr.physics(r.z), dir);
    std::vector<double> z_rest(tries.size());
    rest_matched = std::isfinite(w_cur);
    for (std::size_t i = 0; i < tries.size() && rest_matched; ++i) {
      ctx.region = tries[i].first;
      const double w = model.rest_frequency(pr.physics(tries[i].second), dir);
      rest_matched = std::isfinite(w) && w > 0;
      z_rest[i] = std::clamp(tries[i].second[0] + 2 * std::log(w_cur / w), pr.lo[0], pr.hi[0]);
    }
    ctx.region = keep;
    if (rest_matched)
      for (std::size_t i = 0; i < tries.size(); ++i) tries[i].second[0] = z_rest[i];
  }
  if (!rest_matched) probe_b = run_tries(s, w, M, all);
  // With two modes recorded, each move is put back onto both frequencies: a second probe at the
  // current factor (or 10 % past the first away from the null value, when the two nearly agree)
  // gives the move's own slopes of the frequency ratio and of omega1, and the factor and E go where
  // both meet the recorded ones. (A slope borrowed from the current box fails where it matters:
  // taking the clamped voxel out of a stiff root quarter makes the ratio 7x more sensitive to the
  // factor.)
  if (secant) {
    std::vector<std::vector<double>> z2(tries.size());
    std::vector<Physics> batch2;
    for (std::size_t i = 0; i < tries.size(); ++i) {
      z2[i] = tries[i].second;
      z2[i][2] = std::abs(r.z[2] - z2[i][2]) >= 0.05 ? r.z[2]
                                                     : z2[i][2] + (z2[i][2] >= z_null ? 0.1 : -0.1);
      ctx.region = tries[i].first;
      batch2.push_back(pr.physics(z2[i]));
    }
    ctx.region = keep;
    const auto probe2 = ev.run(batch2);
    for (std::size_t i = 0; i < tries.size(); ++i) {
      const ModePoint pa = mode_point(s, probe_b[i], tries[i].second[2]),
                      pb = mode_point(s, probe2[i], z2[i][2]);
      const auto x = pa.ok && pb.ok ? ratio_crossings({pa, pb}, r_obs) : std::vector<Crossing>();
      if (x.empty()) {
        tries[i].second[0] = match_frequency(s, tries[i].second[0], w_fit, probe_b[i]);
        continue;
      }
      tries[i].second[2] = std::clamp(x[0].zp, pr.lo[2], pr.hi[2]);
      tries[i].second[0] = std::clamp(
          tries[i].second[0] + 2 * (std::log(modes.omega1) - x[0].log_w1), pr.lo[0], pr.hi[0]);
    }
  }
  if (!secant && !rest_matched)
    for (std::size_t i = 0; i < tries.size(); ++i)
      tries[i].second[0] = match_frequency(s, tries[i].second[0], w_fit, probe_b[i]);
  return run_tries(s, w, M, all);
}

//! Each move's Gauss-Newton step in (log E, log factor) jointly, with the current fit's
//! sensitivities (two runs) standing in for each move's: E and the factor trade off along a narrow
//! valley. The best kGnMoves by predicted chi-square take it in a forward run, kept where it lowers
//! their chi-square (M.chi_matched, M.pred_try).
void gauss_newton_moves(State& s, RefitWork& w, const LsqResult& r, Moves& M,
                        const std::vector<Prediction>& pb_runs) {
  const Observations& obs = s.obs;
  Evaluator& ev = *s.ev;
  LsqProblem& pr = w.pr;
  auto& tries = M.tries;
  const std::vector<std::size_t>& all = M.all;
  std::vector<double>& chi_matched = M.chi_matched;
  std::vector<Prediction>& pred_try = M.pred_try;
  // The matched frequency leaves a phase error that can hide a better shape (chi2 moves 10 % for
  // 0.1 % of E over 7 periods), and E and the factor trade off along a narrow valley. So each move
  // takes a Gauss-Newton step in (log E, log factor) jointly, with the sensitivities of the current
  // fit (two runs per round) standing in for each move's; the moves are ranked by the chi2 that
  // step predicts, and the best kGnMoves take it in a forward run.
  const double dz = 1e-3;
  const std::array<std::size_t, 2> gn_cols = {0, 2};  // log E, log stiffness factor
  // r.pred is the current fit's run (kept with each accepted move): only the two perturbed runs are
  // new.
  std::vector<Physics> jb;
  for (std::size_t col : gn_cols) {
    std::vector<double> zd = r.z;
    zd[col] += dz;
    jb.push_back(pr.physics(zd));
  }
  const auto base_runs = ev.run(jb);
  Eigen::MatrixXd J;
  if (r.pred.ok &&
      std::all_of(base_runs.begin(), base_runs.end(), [](const Prediction& p) { return p.ok; })) {
    const Eigen::VectorXd rb = weighted_residual(obs, r.pred, obs.train);
    J.resize(rb.size(), static_cast<Eigen::Index>(gn_cols.size()));
    for (std::size_t k = 0; k < gn_cols.size(); ++k)
      J.col(static_cast<Eigen::Index>(k)) =
          (weighted_residual(obs, base_runs[k], obs.train) - rb) / dz;
  }
  const bool have_j = J.size() > 0;
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> jqr =
      have_j ? Eigen::ColPivHouseholderQR<Eigen::MatrixXd>(J)
             : Eigen::ColPivHouseholderQR<Eigen::MatrixXd>();
  const std::array<double, 2> max_step = {0.05, 0.3};  // |d log E|, |d log f|
  chi_matched.assign(tries.size(), 1e300);
  std::vector<double> chi_predicted(tries.size(), 1e300);
  std::vector<std::vector<double>> z_gn(tries.size());
  pred_try.assign(pb_runs.begin(), pb_runs.end());  // at tries[i].second
  for (std::size_t i = 0; i < tries.size(); ++i) {
    z_gn[i] = tries[i].second;
    if (!pb_runs[i].ok) continue;
    const Eigen::VectorXd r0 = weighted_residual(obs, pb_runs[i], obs.train);
    chi_matched[i] = chi_predicted[i] = r0.squaredNorm();
    if (have_j) {
      Eigen::VectorXd step = jqr.solve(r0);
      // A step past its bound is scaled back as a whole (the valley is diagonal).
      double scale = 1;
      for (std::size_t k = 0; k < gn_cols.size(); ++k)
        if (std::abs(step[static_cast<Eigen::Index>(k)]) > max_step[k])
          scale = std::min(scale, max_step[k] / std::abs(step[static_cast<Eigen::Index>(k)]));
      step *= scale;
      for (std::size_t k = 0; k < gn_cols.size(); ++k) {
        const std::size_t col = gn_cols[k];
        z_gn[i][col] =
            std::clamp(z_gn[i][col] - step[static_cast<Eigen::Index>(k)], pr.lo[col], pr.hi[col]);
      }
      chi_predicted[i] = (r0 - J * step).squaredNorm();
    }
  }
  std::vector<std::size_t> order = all;
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return chi_predicted[a] < chi_predicted[b]; });
  order.resize(std::min(order.size(), have_j ? kGnMoves : std::size_t{0}));
  for (std::size_t i : order) std::swap(tries[i].second, z_gn[i]);
  const auto pg_runs = run_tries(s, w, M, order);
  for (std::size_t k = 0; k < order.size(); ++k) {
    const std::size_t i = order[k];
    const double cg =
        pg_runs[k].ok ? weighted_residual(obs, pg_runs[k], obs.train).squaredNorm() : 1e300;
    if (cg < chi_matched[i])
      chi_matched[i] = cg, pred_try[i] = pg_runs[k];
    else
      std::swap(tries[i].second, z_gn[i]);  // back to the matched point
  }
}

//! One step still leaves a move off its own valley while the current box sits at its optimum: the
//! best kMoveFits moves get a short fit (not on the secant path), unless their chi-square is beyond
//! kMoveFitReach times the current fit's.
void short_fit_moves(State& s, RefitWork& w, const LsqResult& r, Moves& M) {
  EffectContext& ctx = s.ctx;
  Evaluator& ev = *s.ev;
  LsqProblem& pr = w.pr;
  auto& tries = M.tries;
  const BoxRegion& keep = M.keep;
  const std::vector<std::size_t>& all = M.all;
  const bool secant = M.secant;
  std::vector<double>& chi_matched = M.chi_matched;
  std::vector<Prediction>& pred_try = M.pred_try;
  std::vector<std::size_t> by_chi = all;
  std::sort(by_chi.begin(), by_chi.end(),
            [&](std::size_t a, std::size_t b) { return chi_matched[a] < chi_matched[b]; });
  for (std::size_t q = 0; q < std::min(by_chi.size(), secant ? 0 : kMoveFits); ++q) {
    const std::size_t i = by_chi[q];
    if (!(chi_matched[i] < 1e299) || chi_matched[i] > kMoveFitReach * r.chi2) break;
    ctx.region = tries[i].first;
    const LsqResult rs = least_squares(ev, pr, tries[i].second, kRegionStartIterations, false);
    if (rs.pred.ok && rs.chi2 < chi_matched[i])
      chi_matched[i] = rs.chi2, tries[i].second = rs.z, pred_try[i] = rs.pred;
  }
  ctx.region = keep;
}

}  // namespace

void refine_box(State& s, RefitWork& w, LsqResult& r) {
  EffectContext& ctx = s.ctx;
  Evaluator& ev = *s.ev;
  LsqProblem& pr = w.pr;
  const double w_fit = dominant_omega(s.obs, r.pred.y, s.t_free);
  for (int round = 0; round < 8; ++round) {
    Moves M = make_moves(s, w, r, face_moves(s));
    const std::vector<Prediction> pb_runs = match_moves(s, w, r, M, w_fit);
    gauss_newton_moves(s, w, r, M, pb_runs);
    short_fit_moves(s, w, r, M);
    const auto& tries = M.tries;
    double best_chi = r.chi2;
    int pick = -1;
    for (std::size_t i = 0; i < tries.size(); ++i)
      if (M.chi_matched[i] < best_chi) best_chi = M.chi_matched[i], pick = static_cast<int>(i);
    if (pick < 0 || best_chi > 0.995 * r.chi2) break;
    {
      const BoxRegion& nb = tries[static_cast<std::size_t>(pick)].first;
      log::info(
          "  heterogeneity face move {}: [{:.3g} {:.3g} {:.3g}]-[{:.3g} "
          "{:.3g} {:.3g}], "
          "chi2 {:.4g} -> {:.4g}",
          round + 1, nb.lo[0], nb.lo[1], nb.lo[2], nb.hi[0], nb.hi[1], nb.hi[2], r.chi2, best_chi);
    }
    ctx.region = tries[static_cast<std::size_t>(pick)].first;
    r.z = tries[static_cast<std::size_t>(pick)].second;
    r.chi2 = best_chi;
    r.pred = M.pred_try[static_cast<std::size_t>(pick)];
    // Matched moves are compared with a fitted box: the accepted one is fitted too before the next
    // round, or a move that only beats the current box's start is kept where the box it left fits
    // better at its own optimum.
    if (M.secant) {
      const LsqResult rs = least_squares(ev, pr, r.z, kRegionStartIterations, false);
      if (rs.pred.ok && rs.chi2 < r.chi2) r = rs;
    }
  }
}

}  // namespace gen4d::diagnose
