#include "diagnose/Fit.hpp"

#include <petsctao.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <utility>

#include <fmt/format.h>

#include "core/Error.hpp"
#include "diagnose/Effects.hpp"
#include "core/Log.hpp"
#include "parallel/PetscCheck.hpp"
#include "parallel/Comm.hpp"

namespace gen4d::diagnose {

Evaluator::Evaluator(MPI_Comm comm, const ForwardModel& model, const Observations& obs)
    : comm_(comm), model_(model), obs_(obs) {
  rank_ = parallel::rank(comm);
  size_ = parallel::size(comm);
}

void Evaluator::set_horizon(double t) {
  horizon_ = t;
  requests_.clear();
  if (!std::isfinite(t)) return;
  requests_ = obs_.requests;
  for (auto& r : requests_) {
    const auto end = std::upper_bound(r.t.begin(), r.t.end(), t);
    r.t.erase(end, r.t.end());
  }
}

std::string physics_key(const Physics& p, double horizon) {
  // The base physics field by field, then each applied effect's name and term values (an
  // effect at its null values has no entry, so it keys as the base physics).
  std::string k;
  auto put = [&k](const auto& v) { k.append(reinterpret_cast<const char*>(&v), sizeof v); };
  auto put_text = [&](const std::string& s) {
    put(s.size());
    k += s;
  };
  put(p.element);
  put(p.consistent_mass_fraction);
  put_text(p.law);
  put(p.youngs_modulus), put(p.poisson_ratio), put(p.density);
  for (double g : p.gravity) put(g);
  put(p.dt), put(p.load_scale), put(p.time_offset), put(p.release_duration), put(p.lowpass_hz),
      put(p.newton_tolerance), put(p.refresh_contraction);
  put(horizon);
  put(p.effects.size());
  for (const auto& e : p.effects) {
    put_text(e.effect->name());
    put(e.terms.size());
    for (double x : e.terms) put(x);
  }
  return k;
}

std::vector<Prediction> Evaluator::run(const std::vector<Physics>& batch) {
  const auto t_call = std::chrono::steady_clock::now();
  std::vector<Prediction> out(batch.size());
  // What to run: each physics neither in the memo nor earlier in this batch, once.
  std::vector<std::string> keys(batch.size());
  std::vector<std::size_t> todo;                       // batch indices run here
  std::vector<std::ptrdiff_t> from(batch.size(), -1);  // else: memo entry, or -2 - todo slot
  for (std::size_t i = 0; i < batch.size(); ++i) {
    keys[i] = physics_key(batch[i], horizon_);
    for (std::size_t m = 0; m < memo_.size() && from[i] == -1; ++m)
      if (memo_[m].first == keys[i]) from[i] = static_cast<std::ptrdiff_t>(m);
    for (std::size_t q = 0; q < todo.size() && from[i] == -1; ++q)
      if (keys[todo[q]] == keys[i]) from[i] = -2 - static_cast<std::ptrdiff_t>(q);
    if (from[i] == -1) todo.push_back(i);
  }
  double local_seconds = 0;
  const bool cut = std::isfinite(horizon_);
  for (std::size_t q = 0; q < todo.size(); ++q) {
    if (static_cast<int>(q % static_cast<std::size_t>(size_)) != rank_) continue;
    const std::size_t i = todo[q];
    const auto t0 = std::chrono::steady_clock::now();
    const Trace tr = model_.run(batch[i], cut ? requests_ : obs_.requests);
    local_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    Prediction& p = out[i];
    p.ok = tr.ok;
    p.failure = tr.failure;
    p.max_mises = tr.max_mises;
    p.max_speed = tr.max_speed;
    p.continued_points = tr.continued_points;
    if (tr.ok) {
      p.y.reserve(obs_.size());
      for (std::size_t c = 0; c < tr.channel.size(); ++c) {
        if (!obs_.measured.empty() && !obs_.measured[c].empty()) {
          // The measured values only; samples after the horizon: NaN.
          const std::vector<char>& m = obs_.measured[c];
          for (std::size_t j = 0; j < m.size(); ++j)
            if (m[j])
              p.y.push_back(j < tr.channel[c].size() ? tr.channel[c][j]
                                                     : std::numeric_limits<double>::quiet_NaN());
          continue;
        }
        p.y.insert(p.y.end(), tr.channel[c].begin(), tr.channel[c].end());
        // Samples after the horizon: NaN, so a mask that reads them shows at once.
        p.y.resize(p.y.size() + 3 * (obs_.requests[c].t.size() - tr.channel[c].size() / 3),
                   std::numeric_limits<double>::quiet_NaN());
      }
    }
  }
  // Share every result from the rank that computed it.
  for (std::size_t q = 0; q < todo.size(); ++q) {
    const int owner = static_cast<int>(q % static_cast<std::size_t>(size_));
    Prediction& p = out[todo[q]];
    double head[5] = {p.ok ? 1.0 : 0.0, p.max_mises, p.max_speed,
                      static_cast<double>(p.failure.size()),
                      static_cast<double>(p.continued_points)};
    parallel::broadcast(comm_, head, 5, owner);
    p.ok = head[0] != 0.0;
    p.max_mises = head[1];
    p.max_speed = head[2];
    p.failure.resize(static_cast<std::size_t>(head[3]));
    p.continued_points = static_cast<long>(head[4]);
    if (!p.failure.empty()) parallel::broadcast(comm_, p.failure.data(), p.failure.size(), owner);
    if (p.ok) {
      p.y.resize(obs_.size());
      parallel::broadcast(comm_, p.y.data(), p.y.size(), owner);
      if (p.continued_points > 0) ++continued_;
    } else if (failed_++ == 0) {
      first_failure_ = p.failure;
    }
  }
  for (std::size_t i = 0; i < batch.size(); ++i) {
    if (from[i] >= 0)
      out[i] = memo_[static_cast<std::size_t>(from[i])].second;
    else if (from[i] <= -2)
      out[i] = out[todo[static_cast<std::size_t>(-2 - from[i])]];
  }
  // The new results join the memo, the oldest leaving it (the same on every rank).
  for (std::size_t i : todo) {
    memo_.emplace_back(keys[i], out[i]);
    memo_bytes_ += sizeof(double) * out[i].y.size();
    while (memo_bytes_ > kMemoBytes) {
      memo_bytes_ -= sizeof(double) * memo_.front().second.y.size();
      memo_.pop_front();
    }
  }
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_call).count();
  double all[2] = {local_seconds, wall - local_seconds};
  parallel::sum_in_place(comm_, all, 2);
  seconds_ += all[0];
  idle_ += all[1];
  runs_ += static_cast<long>(todo.size());
  reused_ += static_cast<long>(batch.size() - todo.size());
  return out;
}

Eigen::VectorXd weighted_residual(const Observations& obs, const Prediction& p,
                                  const std::vector<char>& mask) {
  std::size_t n = 0;
  for (char m : mask) n += m ? 1 : 0;
  Eigen::VectorXd r(static_cast<Eigen::Index>(n));
  Eigen::Index k = 0;
  for (std::size_t i = 0; i < obs.size(); ++i) {
    if (!mask[i]) continue;
    r[k++] = p.ok ? (p.y[i] - obs.y[i]) / obs.sigma[i] : 100.0;
  }
  return r;
}

std::vector<std::vector<std::size_t>> component_series(
    const Observations& obs, double t_from, bool positions_first,
    const std::function<bool(std::size_t)>& keep) {
  bool any_position = false;
  if (positions_first)
    for (const auto& r : obs.requests) any_position = any_position || !r.acceleration;
  std::map<std::pair<int, int>, std::vector<std::size_t>> ser;
  for (std::size_t i = 0; i < obs.size(); ++i) {
    if (obs.t[i] < t_from || (keep && !keep(i))) continue;
    if (any_position && obs.requests[static_cast<std::size_t>(obs.channel[i])].acceleration)
      continue;
    ser[{obs.channel[i], obs.component[i]}].push_back(i);
  }
  std::vector<std::vector<std::size_t>> out;
  out.reserve(ser.size());
  for (auto& [key, idx] : ser) out.push_back(std::move(idx));
  return out;
}

int main_component(const Observations& obs, int channel) {
  double s[3] = {0, 0, 0}, s2[3] = {0, 0, 0}, n[3] = {0, 0, 0};
  for (std::size_t i = 0; i < obs.size(); ++i) {
    if (obs.channel[i] != channel) continue;
    const int k = obs.component[i];
    s[k] += obs.y[i], s2[k] += obs.y[i] * obs.y[i], n[k] += 1;
  }
  int best = 0;
  double best_var = -1;
  for (int k = 0; k < 3; ++k) {
    const double var = n[k] > 0 ? s2[k] / n[k] - (s[k] / n[k]) * (s[k] / n[k]) : 0.0;
    if (var > best_var) best_var = var, best = k;
  }
  return best;
}

Eigen::VectorXd bounded_gauss_newton_step(const Eigen::MatrixXd& J, const Eigen::VectorXd& r,
                                          const std::vector<double>& z,
                                          const std::vector<double>& lo,
                                          const std::vector<double>& hi) {
  // Bounded-variable least squares (Stark and Parker's BVLS, Lawson and Hanson's active-set
  // scheme with two-sided bounds) in the step s, l = lo - z <= s <= u = hi - z. The iterate
  // stays feasible and |J s + r| never rises: the free parameters' least-squares solution is
  // taken where it lies within the bounds, else the iterate moves towards it as far as the
  // first bound it meets, which then holds that parameter. With the free set solved, a held
  // parameter whose gradient points into the box (its Lagrange multiplier of the wrong sign) is
  // released, the one with the largest first, until none is (the Karush-Kuhn-Tucker conditions
  // of this convex problem: the step is its minimum).
  const auto n = static_cast<Eigen::Index>(z.size());
  Eigen::VectorXd l(n), u(n), s(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    l[k] = std::min(lo[ku] - z[ku], 0.0);
    u[k] = std::max(hi[ku] - z[ku], 0.0);
    s[k] = 0.0;
  }
  // -1 held at l, +1 held at u, 0 free. A parameter that starts on a bound starts free: the
  // first solve and the step towards it hold it again where it would leave the box.
  std::vector<int> state(z.size(), 0);
  const double jn = std::max(J.norm(), 1e-300);
  auto tol_g = [&] { return 1e-11 * jn * ((J * s + r).norm() + 1e-300); };
  const int max_iter = 10 * static_cast<int>(n) + 10;
  int released_last = -1;
  for (int it = 0; it < max_iter; ++it) {
    // The free parameters' least-squares step from the held ones, towards which the iterate
    // moves until it lies within the bounds.
    for (int inner = 0; inner <= static_cast<int>(n); ++inner) {
      std::vector<Eigen::Index> free;
      Eigen::VectorXd rr = r;
      for (Eigen::Index k = 0; k < n; ++k)
        if (state[static_cast<std::size_t>(k)] != 0)
          rr += J.col(k) * s[k];
        else
          free.push_back(k);
      if (free.empty()) break;
      Eigen::MatrixXd Jf(J.rows(), static_cast<Eigen::Index>(free.size()));
      for (std::size_t f = 0; f < free.size(); ++f)
        Jf.col(static_cast<Eigen::Index>(f)) = J.col(free[f]);
      const Eigen::VectorXd y = Jf.colPivHouseholderQr().solve(-rr);
      double alpha = 1.0;
      for (std::size_t f = 0; f < free.size(); ++f) {
        const Eigen::Index k = free[f];
        const double yk = y[static_cast<Eigen::Index>(f)], d = yk - s[k];
        if (yk < l[k] && d < 0) alpha = std::min(alpha, (l[k] - s[k]) / d);
        if (yk > u[k] && d > 0) alpha = std::min(alpha, (u[k] - s[k]) / d);
      }
      alpha = std::clamp(alpha, 0.0, 1.0);
      bool bound_hit = false;
      for (std::size_t f = 0; f < free.size(); ++f) {
        const Eigen::Index k = free[f];
        const double yk = y[static_cast<Eigen::Index>(f)];
        s[k] = alpha == 1.0 ? yk : s[k] + alpha * (yk - s[k]);
        // A parameter the move brought to a bound it was heading past is held there (the one
        // just released is not held again at once on rounding: it would cycle).
        const bool past_l = yk < l[k] && s[k] <= l[k] + 1e-14 * (1 + std::abs(l[k]));
        const bool past_u = yk > u[k] && s[k] >= u[k] - 1e-14 * (1 + std::abs(u[k]));
        if ((past_l || past_u) && !(k == released_last && alpha == 0.0)) {
          s[k] = past_l ? l[k] : u[k];
          state[static_cast<std::size_t>(k)] = past_l ? -1 : 1;
          bound_hit = true;
        }
        s[k] = std::clamp(s[k], l[k], u[k]);
      }
      if (!bound_hit) break;
    }
    // The multipliers of the held parameters: the gradient J^T (J s + r) must point out of
    // the box at each (non-negative at a lower bound, non-positive at an upper one).
    const Eigen::VectorXd g = J.transpose() * (J * s + r);
    const double tg = tol_g();
    Eigen::Index worst = -1;
    double worst_g = tg;
    for (Eigen::Index k = 0; k < n; ++k) {
      const int st = state[static_cast<std::size_t>(k)];
      const double wrong = st < 0 ? -g[k] : st > 0 ? g[k] : 0.0;
      if (wrong > worst_g) worst_g = wrong, worst = k;
    }
    if (worst < 0) break;
    state[static_cast<std::size_t>(worst)] = 0;
    released_last = static_cast<int>(worst);
  }
  return s;
}

double conditional_standard_error(const Eigen::MatrixXd& J, Eigen::Index j, double s2) {
  const Eigen::VectorXd col = J.col(j);
  const double n0 = col.norm();
  if (!(n0 > 0) || !std::isfinite(n0)) return std::numeric_limits<double>::infinity();
  Eigen::VectorXd rest = col;
  if (J.cols() > 1) {
    Eigen::MatrixXd others(J.rows(), J.cols() - 1);
    for (Eigen::Index c = 0, k = 0; c < J.cols(); ++c)
      if (c != j) others.col(k++) = J.col(c);
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(others);
    rest = col - others * qr.solve(col);
  }
  const double n1 = rest.norm();
  if (!(n1 > 1e-10 * n0)) return std::numeric_limits<double>::infinity();
  return std::sqrt(s2) / n1;
}

double rms(const Observations& obs, const Prediction& p, const std::vector<char>& mask) {
  // Positions (m) when the recording has any, else accelerations (m/s^2): never a mix of units.
  bool any_position = false;
  for (std::size_t i = 0; i < obs.size() && !any_position; ++i)
    any_position = mask[i] && !obs.requests[static_cast<std::size_t>(obs.channel[i])].acceleration;
  double s = 0;
  long n = 0;
  for (std::size_t i = 0; i < obs.size(); ++i) {
    if (!mask[i] || !p.ok) continue;
    if (any_position && obs.requests[static_cast<std::size_t>(obs.channel[i])].acceleration)
      continue;
    const double d = p.y[i] - obs.y[i];
    s += d * d;
    ++n;
  }
  return n ? std::sqrt(s / static_cast<double>(n)) : std::nan("");
}

namespace {

struct TaoContext {
  Evaluator* ev;
  const LsqProblem* prob;
  std::vector<double> z_cached;
  Prediction pred_cached;
  Eigen::VectorXd r_cached;
  bool have_cached = false;
  std::vector<double> z_jac;
  double chi2_jac = 0;  //!< chi2 at z_jac
  Eigen::MatrixXd J;
  // best point seen
  std::vector<double> z_best;
  Prediction pred_best;
  Eigen::VectorXd r_best;
  double chi2_best = 1e300;
  long runs = 0;
  //! 1 / f(z0): TAO's bound-activity estimate and tolerances expect an O(1) objective.
  double scale = 1;
  double f_prev = 0;
  int stalls = 0;
  bool abandoned = false;
  long skipped = 0;  //!< line-search points not run (below the step tolerance)
  //! The linearisation point whose line search fell below the step tolerance.
  std::vector<double> z_converged;
  long max_runs = 1000;  //!< forward runs one fit may spend
  int max_iterations = 0;
};

std::vector<double> to_std(Vec X) {
  PetscInt n;
  VecGetLocalSize(X, &n);
  const PetscScalar* a;
  VecGetArrayRead(X, &a);
  std::vector<double> z(a, a + n);
  VecRestoreArrayRead(X, &a);
  return z;
}

void note(TaoContext& c, const std::vector<double>& z, const Prediction& p,
          const Eigen::VectorXd& r) {
  c.z_cached = z;
  c.pred_cached = p;
  c.r_cached = r;
  c.have_cached = true;
  const double chi2 = r.squaredNorm();
  if (p.ok && chi2 < c.chi2_best) {
    c.chi2_best = chi2;
    c.z_best = z;
    c.pred_best = p;
    c.r_best = r;
  }
}

//! The forward-difference point of column j at z, and its step.
std::vector<double> fd_point(const TaoContext& c, const std::vector<double>& z, std::size_t j,
                             double& h) {
  std::vector<double> zj = z;
  h = c.prob->step[j];
  if (zj[j] + h > c.prob->hi[j]) h = -h;
  zj[j] += h;
  return zj;
}

//! One point's run. A lone run leaves ranks - 1 ranks idle; they run the first columns of the
//! point's forward-difference Jacobian meanwhile, which jacobian_at finds in the evaluator's
//! memo if the point is accepted (a Gauss-Newton fit accepts most trial points): with 2 ranks
//! and 3 parameters an iteration is 2 rounds of runs instead of 3. The fit itself is
//! unchanged, bit for bit (a run's result does not depend on the rank or batch), and counts
//! its runs as before (c.runs drives its budget); the evaluator counts the runs made ahead too.
void evaluate_at(TaoContext& c, const std::vector<double>& z) {
  if (c.have_cached && c.z_cached == z) return;
  std::vector<Physics> batch = {c.prob->physics(z)};
  // Only as many columns as save a round of the Jacobian's batch (n mod ranks): a column run
  // ahead that saves none only slows the trial run beside it (two runs at once share the
  // memory bus and caches).
  const auto P = static_cast<std::size_t>(std::max(c.ev->ranks(), 1));
  const std::size_t ahead = z.size() % P;
  for (std::size_t j = 0; j < ahead; ++j) {
    double h;
    batch.push_back(c.prob->physics(fd_point(c, z, j, h)));
  }
  const auto preds = c.ev->run(batch);
  ++c.runs;
  note(c, z, preds[0], weighted_residual(c.ev->observations(), preds[0], *c.prob->mask));
}

//! Forward-difference Jacobian at z, columns computed in one parallel batch (those run ahead
//! with z itself come from the evaluator's memo).
void jacobian_at(TaoContext& c, const std::vector<double>& z) {
  const std::size_t n = z.size();
  std::vector<Physics> batch;
  std::vector<double> h(n);
  const bool need_base = !(c.have_cached && c.z_cached == z);
  if (need_base) batch.push_back(c.prob->physics(z));
  const std::size_t first = batch.size();
  for (std::size_t j = 0; j < n; ++j) batch.push_back(c.prob->physics(fd_point(c, z, j, h[j])));
  const auto preds = c.ev->run(batch);
  c.runs += static_cast<long>(n + (need_base ? 1 : 0));
  if (need_base)
    note(c, z, preds[0], weighted_residual(c.ev->observations(), preds[0], *c.prob->mask));
  c.J.resize(c.r_cached.size(), static_cast<Eigen::Index>(n));
  // A column whose forward point's run failed (the body gave way past it) is taken from the
  // other side of z where z's own run did not: the failure's stand-in residual is no
  // derivative. Where that run fails too, or lies past the other bound, the column is zero:
  // the data say nothing about the parameter here that a step could use.
  std::vector<std::ptrdiff_t> back(n, -1);  // column j's backward run in back_batch, or -1
  std::vector<Physics> back_batch;
  for (std::size_t j = 0; j < n; ++j)
    if (!preds[first + j].ok && c.pred_cached.ok) {
      std::vector<double> zb = z;
      zb[j] -= h[j];
      if (zb[j] < c.prob->lo[j] || zb[j] > c.prob->hi[j]) continue;
      back[j] = static_cast<std::ptrdiff_t>(back_batch.size());
      back_batch.push_back(c.prob->physics(zb));
    }
  // Only where a column needs it: a batch costs the ranks a reduction even when empty.
  const auto back_preds = back_batch.empty() ? std::vector<Prediction>() : c.ev->run(back_batch);
  c.runs += static_cast<long>(back_batch.size());
  for (std::size_t j = 0; j < n; ++j) {
    const auto col = static_cast<Eigen::Index>(j);
    const bool backward = back[j] >= 0;
    const Prediction& pj =
        backward ? back_preds[static_cast<std::size_t>(back[j])] : preds[first + j];
    if (!pj.ok && c.pred_cached.ok) {
      c.J.col(col).setZero();
      log::info("    fit: parameter {}'s difference runs failed both sides of z: {}", j,
                pj.failure);
      continue;
    }
    const double hj = backward ? -h[j] : h[j];
    if (backward)
      log::info("    fit: parameter {}'s forward difference failed; backward instead", j);
    const Eigen::VectorXd rj = weighted_residual(c.ev->observations(), pj, *c.prob->mask);
    c.J.col(col) = (rj - c.r_cached) / hj;
  }
  c.z_jac = z;
  c.chi2_jac = c.r_cached.squaredNorm();
  std::string zs;
  for (double v : z) zs += fmt::format(" {:.5g}", v);
  log::info("    fit: chi2 {:.6g} at z ={} ({} runs so far)", c.chi2_jac, zs, c.runs);
}

//! TAO's default test, plus: stop when two successive iterations each lower the objective by
//! less than 1e-3 of it. A recording never fits to its noise (discretisation, unmodelled
//! detail), and the last permille of chi-square is the E-nu valley absorbing that discrepancy
//! one slow step at a time: it changes no verdict and costs most of a fit's runs.
PetscErrorCode tao_convergence(Tao tao, void* ctx) {
  PetscCall(TaoDefaultConvergenceTest(tao, nullptr));
  auto& c = *static_cast<TaoContext*>(ctx);
  PetscInt its;
  PetscReal f, gnorm, cnorm, xdiff;
  TaoConvergedReason reason;
  PetscCall(TaoGetSolutionStatus(tao, &its, &f, &gnorm, &cnorm, &xdiff, &reason));
  if (reason != TAO_CONTINUE_ITERATING) return 0;
  if (c.runs > c.max_runs) {
    PetscCall(TaoSetConvergedReason(tao, TAO_DIVERGED_MAXFCN));
    return 0;
  }
  c.stalls = its > 0 && c.f_prev - f < 1e-3 * c.f_prev ? c.stalls + 1 : 0;
  // Projected: chi2 times the last iteration's ratio to the power of the iterations left.
  const double projected =
      c.f_prev > 0 ? c.chi2_best * std::pow(std::min(1.0, f / c.f_prev),
                                            std::max(0, c.max_iterations - static_cast<int>(its)))
                   : 0.0;
  const bool stalled_far = its >= kAbandonAfter && c.chi2_best > c.prob->compete_chi2 &&
                           projected > c.prob->compete_chi2;
  if ((its >= kAbandonAfter && c.chi2_best > c.prob->abandon_chi2 && f > 0.5 * c.f_prev) ||
      stalled_far) {
    if (stalled_far)
      log::info(
          "    fit: given up: chi2 {:.6g}, at this iteration's rate {:.4g} at the limit "
          "(needs < {:.6g})",
          c.chi2_best, projected, c.prob->compete_chi2);
    c.abandoned = true;
    PetscCall(TaoSetConvergedReason(tao, TAO_CONVERGED_USER));
    return 0;
  }
  c.f_prev = f;
  if (c.stalls >= 2) PetscCall(TaoSetConvergedReason(tao, TAO_CONVERGED_USER));
  return 0;
}

//! f = |r|^2 / 2 and g = J^T r, with the Jacobian's columns run in parallel.
PetscErrorCode tao_objective_gradient(Tao, Vec X, PetscReal* f, Vec G, void* ctx) {
  auto& c = *static_cast<TaoContext*>(ctx);
  const std::vector<double> z = to_std(X);
  if (c.runs >= c.max_runs) {  // budget spent: a zero gradient ends the solve (best kept)
    *f = c.scale * 0.5 * c.chi2_best;
    PetscCall(VecSet(G, 0.0));
    return 0;
  }
  evaluate_at(c, z);
  if (!(z == c.z_jac && c.J.rows() == c.r_cached.size())) jacobian_at(c, z);
  *f = c.scale * 0.5 * c.r_cached.squaredNorm();
  const Eigen::VectorXd g = c.scale * (c.J.transpose() * c.r_cached);
  PetscScalar* a;
  PetscCall(VecGetArray(G, &a));
  for (Eigen::Index i = 0; i < g.size(); ++i) a[i] = g[i];
  PetscCall(VecRestoreArray(G, &a));
  return 0;
}

//! The fits' step tolerance, in finite-difference steps of each parameter: a trial point
//! closer than this to the last linearisation point in every parameter moves log E by less
//! than 1e-6 (and nu by 1e-5). On the blind beams that shifts the 22 rad/s mode's phase by
//! 2e-5 rad over 2 s, 1e-7 m of motion: Newton's stopping tolerance in a run (1e-5 voxel).
constexpr double kStepTolerance = 1e-3;

bool below_step_tolerance(const TaoContext& c, const std::vector<double>& z) {
  if (c.z_jac.size() != z.size()) return false;
  for (std::size_t j = 0; j < z.size(); ++j)
    if (std::abs(z[j] - c.z_jac[j]) >= kStepTolerance * c.prob->step[j]) return false;
  return true;
}

//! Objective alone (line-search trial points): one forward run. A line search that backtracks
//! below the step tolerance has converged (the Gauss-Newton step there is one that moves
//! nothing): the point is not run and is given the objective of the point the search left,
//! raised by 1e-9 of it so that the search cannot accept a point that was not run (at a tiny
//! step Armijo's required decrease rounds to zero); the search fails, TAO's fallback searches
//! from the same point (scaled gradient, gradient) are refused the same way, and the fit ends
//! at its best point.
//! A fit's floor cost 35-53 lone runs on blind recordings before, the halvings of up to 30 per
//! search and the fallbacks' own.
PetscErrorCode tao_objective(Tao, Vec X, PetscReal* f, void* ctx) {
  auto& c = *static_cast<TaoContext*>(ctx);
  if (c.runs >= c.max_runs) {
    *f = c.scale * 0.5 * c.chi2_best;
    return 0;
  }
  const std::vector<double> z = to_std(X);
  const bool converged = !c.z_converged.empty() && c.z_converged == c.z_jac;
  if (converged || below_step_tolerance(c, z)) {
    if (!converged) {
      c.z_converged = c.z_jac;
      log::info("    fit: line search below the step tolerance: converged");
    }
    ++c.skipped;
    *f = c.scale * 0.5 * c.chi2_jac * (1 + 1e-9);
    return 0;
  }
  evaluate_at(c, z);
  // A trial point whose run failed lies outside the model's domain: an infinite objective,
  // from which TAO's Armijo search backs off (halving the step). The failure's stand-in
  // residual (weighted_residual: 100 noise sd a value) would undercut a misfit of more than
  // 100 sd and be taken as a descent.
  *f = c.pred_cached.ok ? c.scale * 0.5 * c.r_cached.squaredNorm() : PETSC_INFINITY;
  return 0;
}

//! Gauss-Newton Hessian J^T J (plus a tiny ridge so flat directions stay invertible).
PetscErrorCode tao_hessian(Tao, Vec X, Mat H, Mat, void* ctx) {
  auto& c = *static_cast<TaoContext*>(ctx);
  const std::vector<double> z = to_std(X);
  if (c.runs < c.max_runs && !(z == c.z_jac && c.J.rows() == c.r_cached.size())) {
    evaluate_at(c, z);
    jacobian_at(c, z);
  }
  Eigen::MatrixXd JtJ = c.scale * (c.J.transpose() * c.J);
  const double ridge = 1e-9 * std::max(JtJ.trace(), 1e-300);
  const Eigen::Index n = JtJ.rows();
  PetscScalar* a;
  PetscCall(MatDenseGetArray(H, &a));
  for (Eigen::Index j = 0; j < n; ++j)
    for (Eigen::Index i = 0; i < n; ++i) a[j * n + i] = JtJ(i, j) + (i == j ? ridge : 0.0);
  PetscCall(MatDenseRestoreArray(H, &a));
  PetscCall(MatAssemblyBegin(H, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(H, MAT_FINAL_ASSEMBLY));
  return 0;
}

}  // namespace

LsqResult least_squares(Evaluator& ev, const LsqProblem& prob, std::vector<double> z0,
                        int max_iterations, bool final_jacobian) {
  if (z0.size() + prob.tail.size() == prob.lo.size())
    z0.insert(z0.end(), prob.tail.begin(), prob.tail.end());
  const PetscInt n = static_cast<PetscInt>(z0.size());
  for (std::size_t j = 0; j < z0.size(); ++j) z0[j] = std::clamp(z0[j], prob.lo[j], prob.hi[j]);
  TaoContext c;
  c.ev = &ev;
  c.prob = &prob;
  LsqResult res;
  if (n == 0) {
    evaluate_at(c, z0);
    res.z = z0;
    res.pred = c.pred_cached;
    res.r = c.r_cached;
    res.chi2 = res.r.squaredNorm();
    res.runs = c.runs;
    res.J.resize(res.r.size(), 0);
    res.reason = "no free parameter";
    return res;
  }
  evaluate_at(c, z0);
  c.scale = 1.0 / std::max(0.5 * c.r_cached.squaredNorm(), 1e-300);
  c.max_runs = static_cast<long>((n + 2) * (max_iterations + 2));
  c.max_iterations = max_iterations;
  Vec x, xl, xu;
  Mat H;
  Tao tao;
  parallel::check(VecCreateSeq(PETSC_COMM_SELF, n, &x), "VecCreateSeq");
  parallel::check(VecDuplicate(x, &xl), "VecDuplicate");
  parallel::check(VecDuplicate(x, &xu), "VecDuplicate");
  parallel::check(MatCreateSeqDense(PETSC_COMM_SELF, n, n, nullptr, &H), "MatCreateSeqDense");
  for (PetscInt j = 0; j < n; ++j) {
    parallel::check(VecSetValue(x, j, z0[static_cast<std::size_t>(j)], INSERT_VALUES),
                    "VecSetValue");
    parallel::check(VecSetValue(xl, j, prob.lo[static_cast<std::size_t>(j)], INSERT_VALUES),
                    "VecSetValue");
    parallel::check(VecSetValue(xu, j, prob.hi[static_cast<std::size_t>(j)], INSERT_VALUES),
                    "VecSetValue");
  }
  for (Vec v : {x, xl, xu}) {
    parallel::check(VecAssemblyBegin(v), "VecAssemblyBegin");
    parallel::check(VecAssemblyEnd(v), "VecAssemblyEnd");
  }
  parallel::check(TaoCreate(PETSC_COMM_SELF, &tao), "TaoCreate");
  // Bounded Newton line search on |r|^2 / 2 with the Gauss-Newton Hessian: a bounded
  // Gauss-Newton method whose steps TAO safeguards.
  parallel::check(TaoSetType(tao, TAOBNLS), "TaoSetType");
  parallel::check(TaoSetOptionsPrefix(tao, "diagnose_"), "TaoSetOptionsPrefix");
  parallel::check(TaoSetSolution(tao, x), "TaoSetSolution");
  parallel::check(TaoSetVariableBounds(tao, xl, xu), "TaoSetVariableBounds");
  parallel::check(TaoSetObjective(tao, tao_objective, &c), "TaoSetObjective");
  parallel::check(TaoSetObjectiveAndGradient(tao, nullptr, tao_objective_gradient, &c),
                  "TaoSetObjectiveAndGradient");
  parallel::check(TaoSetHessian(tao, H, H, tao_hessian, &c), "TaoSetHessian");
  // Backtracking (Armijo) line search: a trial point costs one forward run (the objective),
  // the Jacobian's n runs are spent only on the accepted one. TAO's default More-Thuente search
  // asks for the gradient at every trial: near a fit's floor, where the Gauss-Newton step is
  // cut again and again, that was (n + 1) runs per trial and over half of a refit's runs.
  TaoLineSearch ls;
  parallel::check(TaoGetLineSearch(tao, &ls), "TaoGetLineSearch");
  parallel::check(TaoLineSearchSetType(ls, TAOLINESEARCHARMIJO), "TaoLineSearchSetType");
  parallel::check(TaoSetTolerances(tao, 1e-10, 1e-5, 1e-4), "TaoSetTolerances");
  parallel::check(TaoSetMaximumIterations(tao, max_iterations), "TaoSetMaximumIterations");
  // Line-search trial points count too: a fit costs at most this many objective evaluations.
  parallel::check(TaoSetMaximumFunctionEvaluations(tao, 2 * max_iterations + 4),
                  "TaoSetMaximumFunctionEvaluations");
  parallel::check(TaoSetConvergenceTest(tao, tao_convergence, &c), "TaoSetConvergenceTest");
  parallel::check(TaoSetFromOptions(tao), "TaoSetFromOptions");
  parallel::check(TaoSolve(tao), "TaoSolve");
  TaoConvergedReason reason;
  PetscInt its;
  parallel::check(TaoGetConvergedReason(tao, &reason), "TaoGetConvergedReason");
  parallel::check(TaoGetIterationNumber(tao, &its), "TaoGetIterationNumber");
  res.reason = c.abandoned              ? "ABANDONED (cannot compete)"
               : !c.z_converged.empty() ? "CONVERGED_STEPTOL (line search below the step tolerance)"
                                        : TaoConvergedReasons[reason];
  res.abandoned = c.abandoned;
  res.at_limit = !c.abandoned && c.z_converged.empty() &&
                 (reason == TAO_DIVERGED_MAXITS || reason == TAO_DIVERGED_MAXFCN);
  res.skipped = c.skipped;
  res.iterations = static_cast<int>(its);
  log::info("    fit: TAO {} after {} iterations", res.reason, its);
  parallel::check(TaoDestroy(&tao), "TaoDestroy");
  parallel::check(MatDestroy(&H), "MatDestroy");
  for (Vec* v : {&x, &xl, &xu}) parallel::check(VecDestroy(v), "VecDestroy");

  if (c.z_best.empty()) {  // every run failed
    res.z = z0;
    res.pred = c.pred_cached;
    res.r = c.r_cached;
    res.chi2 = res.r.squaredNorm();
    res.runs = c.runs;
    return res;
  }
  res.z = c.z_best;
  res.pred = c.pred_best;
  res.r = c.r_best;
  res.chi2 = c.chi2_best;
  if (c.z_jac != res.z && final_jacobian) {
    c.z_cached = res.z;
    c.pred_cached = res.pred;
    c.r_cached = res.r;
    c.have_cached = true;
    jacobian_at(c, res.z);
  }
  if (c.z_jac == res.z) res.J = c.J;
  res.runs = c.runs;
  return res;
}

std::vector<double> continuation_windows(const Observations& obs, double t_from, double omega) {
  std::vector<double> w;
  if (obs.t.empty() || !(omega > 0) || !std::isfinite(omega)) return w;
  const double t_end = *std::max_element(obs.t.begin(), obs.t.end());
  const double period = 2 * kPi / omega;
  for (double span = 1.5 * period; t_from + span < t_end - period; span *= 2)
    w.push_back(t_from + span);
  return w;
}

LsqResult window_fit(Evaluator& ev, const LsqProblem& prob, const std::vector<double>& z0, double w,
                     int iterations) {
  const Observations& obs = ev.observations();
  std::vector<char> mask = *prob.mask;
  for (std::size_t i = 0; i < obs.size(); ++i)
    if (obs.t[i] > w) mask[i] = 0;
  LsqResult rw;
  if (std::none_of(mask.begin(), mask.end(), [](char m) { return m != 0; })) {
    rw.z = z0;
    rw.reason = "no value in the window";
    return rw;
  }
  LsqProblem pw = prob;
  pw.mask = &mask;
  pw.abandon_chi2 = std::numeric_limits<double>::infinity();  // set for the whole recording
  pw.compete_chi2 = std::numeric_limits<double>::infinity();
  struct Horizon {  // runs stop at w for this fit only, whatever way it ends
    Evaluator& ev;
    Horizon(Evaluator& e, double t) : ev(e) { ev.set_horizon(t); }
    ~Horizon() { ev.set_horizon(std::numeric_limits<double>::infinity()); }
  } horizon(ev, w);
  rw = least_squares(ev, pw, z0, iterations, false);
  log::info("    fit: window t <= {:.3g} s: chi2 {:.6g} ({} runs)", w, rw.chi2, rw.runs);
  return rw;
}

LsqResult continuation_fit(Evaluator& ev, const LsqProblem& prob, std::vector<double> z0,
                           const std::vector<double>& windows, int window_iterations,
                           int final_iterations, bool final_jacobian) {
  const Observations& obs = ev.observations();
  long runs = 0, skipped = 0;
  for (double w : windows) {
    const LsqResult rw = window_fit(ev, prob, z0, w, window_iterations);
    runs += rw.runs;
    skipped += rw.skipped;
    if (rw.pred.ok) z0 = rw.z;
  }
  LsqResult r;
  if (final_iterations > 0) {
    r = least_squares(ev, prob, z0, final_iterations, final_jacobian);
  } else {  // the last window's optimum, scored on the whole recording (one run)
    r.z = z0;
    r.pred = ev.run_one(prob.physics(z0));
    r.r = weighted_residual(obs, r.pred, *prob.mask);
    r.chi2 = r.r.squaredNorm();
    r.runs = 1;
    r.reason = "windows only";
  }
  r.runs += runs;
  r.skipped += skipped;
  return r;
}

}  // namespace gen4d::diagnose
