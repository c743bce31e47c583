//! Forward runs spread over ranks, and bounded nonlinear least squares with PETSc TAO (BRGN,
//! Gauss-Newton with finite-difference Jacobians whose columns run in parallel).
#pragma once

#include <Eigen/Dense>
#include <deque>
#include <functional>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "diagnose/Forward.hpp"
#include "parallel/Comm.hpp"

namespace gen4d::diagnose {

constexpr double kPi = 3.14159265358979323846;

//! The observations: every measured value of every sample of every channel, flattened channel
//! by channel, sample by sample, component by component; `sigma` weights each one (noise of its
//! channel kind).
struct Observations {
  std::vector<ChannelRequest> requests;
  std::vector<std::string> ids;
  std::vector<double> y;       //!< observed values
  std::vector<double> t;       //!< time of each value
  std::vector<int> channel;    //!< channel of each value
  std::vector<int> component;  //!< 0, 1, 2
  std::vector<double> sigma;   //!< noise of each value
  std::vector<char> train;     //!< used by the fits
  std::vector<char> heldout;   //!< used only to score
  //! Per channel, per requested sample and component (3 k + d): 1 where the value was measured
  //! (and so is one of y); empty: every value (of every channel, or of that channel) measured.
  std::vector<std::vector<char>> measured;
  std::size_t size() const { return y.size(); }
};

struct Prediction {
  bool ok = false;
  std::string failure;
  std::vector<double> y;  //!< same layout as Observations::y
  double max_mises = 0, max_speed = 0;
  long continued_points = 0;  //!< Trace::continued_points
};

//! Runs batches of forward models, each on one rank, results shared by all ranks. A run is
//! deterministic, so a physics already run (at the same horizon) is taken from a memo of the
//! latest results (kMemoBytes of predicted values at most) instead of run again, on every rank
//! alike.
class Evaluator {
 public:
  static constexpr std::size_t kMemoBytes = std::size_t{256} << 20;
  Evaluator(MPI_Comm comm, const ForwardModel& model, const Observations& obs);
  std::vector<Prediction> run(const std::vector<Physics>& batch);
  Prediction run_one(const Physics& p) { return run({p})[0]; }
  long runs() const { return runs_; }      //!< forward runs made
  long reused() const { return reused_; }  //!< runs asked for and taken from the memo
  //! Forward runs made that failed (a step that did not converge, a singular matrix), and the
  //! first one's reason: a fit whose probes fail near its best point says where the model
  //! gives way, not only that it did.
  long failed() const { return failed_; }
  const std::string& first_failure() const { return first_failure_; }
  //! Forward runs made (not failed) in which StVK's stress was continued below its stable
  //! stretch (Trace::continued_points > 0): parameters that crush part of the body.
  long continued() const { return continued_; }
  double run_seconds() const { return seconds_; }  //!< summed over ranks' runs
  //! Summed over ranks: the time in run() not spent running (waiting for the other ranks'
  //! runs, sharing the results). With P ranks, P x (wall in run()) = run + idle seconds.
  double idle_seconds() const { return idle_; }
  const Observations& observations() const { return obs_; }
  const ForwardModel& model() const { return model_; }
  MPI_Comm comm() const { return comm_; }
  int ranks() const { return size_; }
  //! Runs stop at time t (infinity: the recording's end). Values after t are NaN and must be
  //! outside the mask of whatever reads them (a fit of the first part of a recording).
  void set_horizon(double t);
  double horizon() const { return horizon_; }

 private:
  MPI_Comm comm_;
  int rank_ = 0, size_ = 1;
  const ForwardModel& model_;
  const Observations& obs_;
  double horizon_ = std::numeric_limits<double>::infinity();
  std::vector<ChannelRequest> requests_;  //!< obs_.requests cut at horizon_
  long runs_ = 0, reused_ = 0, failed_ = 0, continued_ = 0;
  std::string first_failure_;
  double seconds_ = 0, idle_ = 0;
  std::deque<std::pair<std::string, Prediction>> memo_;  //!< oldest first
  std::size_t memo_bytes_ = 0;
};

//! The bytes of every field of a Physics (with a horizon): equal keys, equal runs.
std::string physics_key(const Physics& p, double horizon);

//! Weighted residual (pred - obs) / sigma on the observations where mask is set; a failed
//! run gives a large constant residual so optimisers step back.
Eigen::VectorXd weighted_residual(const Observations& obs, const Prediction& p,
                                  const std::vector<char>& mask);
//! The observations grouped into time series: the indices of each (channel, component), in
//! time order, the series ordered by (channel, component). Only values at t >= t_from for
//! which keep(i) holds (all when keep is empty); with positions_first, accelerometer channels
//! are left out when the recording has a marker (acceleration weights the higher modes by
//! omega^2, so a frequency read off them differs).
std::vector<std::vector<std::size_t>> component_series(
    const Observations& obs, double t_from = -std::numeric_limits<double>::infinity(),
    bool positions_first = false, const std::function<bool(std::size_t)>& keep = {});
//! The component (0, 1, 2) of a channel whose observed values vary most.
int main_component(const Observations& obs, int channel);
//! Root mean square of (pred - obs) over mask: of the positions (m) when the recording has
//! markers, else of the accelerations (m/s^2).
double rms(const Observations& obs, const Prediction& p, const std::vector<char>& mask);

//! Standard error of parameter j of a least-squares fit with Jacobian J and residual variance
//! s2, the others re-optimised: sqrt(s2) over the norm of J's column j with its projection on
//! the other columns removed (the Schur complement of J^T J; equal to sqrt(cov_jj) when J has
//! full rank). Infinite when the column lies in the span of the others (to 1e-10 of its norm)
//! or is zero: the data do not constrain the parameter, whose interval is then its range (the
//! pseudo-inverse of J^T J would give a variance of zero there).
double conditional_standard_error(const Eigen::MatrixXd& J, Eigen::Index j, double s2);

//! The Gauss-Newton step s minimising |J s + r| with z + s within [lo, hi] (bounded-variable
//! least squares by active sets: a parameter the free step takes past a bound is held at that
//! bound and the rest solved again; a held one whose gradient points back into the box is
//! released). Along a ridge that ends at a bound (a drag term at zero) the unconstrained step
//! asks the bounded parameter to go past it and sets the others for that move, so clamping
//! it afterwards leaves them where they do not fit. Where z lies outside its bounds, the
//! step does not take it further out.
Eigen::VectorXd bounded_gauss_newton_step(const Eigen::MatrixXd& J, const Eigen::VectorXd& r,
                                          const std::vector<double>& z,
                                          const std::vector<double>& lo,
                                          const std::vector<double>& hi);

//! Iterations before a fit may be given up (LsqProblem::abandon_chi2). On the blind
//! heterogeneity-soft recording the four fits given up (gravity, three damping variants) were
//! at 16-18x the passing fit's chi-square after their second iteration; the third lowered it
//! by 0.01-1.4 % at 4-6 runs each (3 before).
constexpr int kAbandonAfter = 2;

//! A bounded least-squares problem in internal coordinates z (log of positive parameters).
struct LsqProblem {
  std::vector<double> lo, hi;  //!< bounds on z
  std::vector<double> step;    //!< finite-difference step on z
  //! Physics of a point z.
  std::function<Physics(const std::vector<double>& z)> physics;
  //! Start values of trailing parameters (a release state): a start z0 shorter than lo is
  //! completed with them.
  std::vector<double> tail;
  const std::vector<char>* mask = nullptr;  //!< observations fitted
  //! A fit whose chi-square stays above this after kAbandonAfter iterations, and no longer
  //! halves per iteration, is given up (it cannot compete with a fit that already reached a
  //! tenth of it).
  double abandon_chi2 = std::numeric_limits<double>::infinity();
  //! A fit above this after kAbandonAfter iterations is also given up when its last
  //! iteration's rate of decrease, kept over the iterations it has left, would not bring it
  //! below this (nearly stalled far from a fit that passes).
  double compete_chi2 = std::numeric_limits<double>::infinity();
};

struct LsqResult {
  std::vector<double> z;
  Prediction pred;
  Eigen::VectorXd r;  //!< weighted residual at z
  Eigen::MatrixXd J;  //!< its Jacobian (forward differences) at z
  double chi2 = 0;
  int iterations = 0;
  long runs = 0;
  std::string reason;  //!< TAO's converged reason
  //! Stopped by its iteration or run limit (TAO's MAXITS or MAXFCN; not abandoned, not at the
  //! step tolerance): the objective may still be descending, and a continuation from z pays.
  bool at_limit = false;
  bool abandoned = false;  //!< stopped by LsqProblem::abandon_chi2 or compete_chi2
  long skipped = 0;        //!< line-search points not run: below the step tolerance
};

//! The ends of the time windows of a continuation fit: t_from + 1.5 T 2^k (T = 2 pi / omega,
//! the dominant period) while before the recording's last sample less one period; empty when
//! the recording is too short for a window.
std::vector<double> continuation_windows(const Observations& obs, double t_from, double omega);

//! least_squares on the recording up to time w (runs stopped there; the mask cut there too),
//! from z0; with nothing to fit there, z0 unchanged and no run.
LsqResult window_fit(Evaluator& ev, const LsqProblem& prob, const std::vector<double>& z0, double w,
                     int iterations);

//! least_squares on the recording up to each window end in turn (runs stopped there), each
//! fit starting from the last, then on all of it (final_iterations). Trajectory least squares
//! has a local minimum per period of phase error, and a parameter that moves a frequency
//! (a region's stiffness, a clamp's) puts a start many periods out of phase by the end of the
//! recording but less than half a period within a window of a few periods; so the window fits
//! keep to the basin that holds the right phase and the full fit refines it. With no windows
//! it is least_squares. The result counts the runs of all the fits.
LsqResult continuation_fit(Evaluator& ev, const LsqProblem& prob, std::vector<double> z0,
                           const std::vector<double>& windows, int window_iterations,
                           int final_iterations, bool final_jacobian = true);

//! Minimises |r(z)|^2 from z0 with TAO BRGN; every rank runs the same iterations. The
//! result's J is the Jacobian at the optimum; when the last one TAO computed was elsewhere it is
//! computed (n runs) only if final_jacobian, else J is left empty.
LsqResult least_squares(Evaluator& ev, const LsqProblem& prob, std::vector<double> z0,
                        int max_iterations, bool final_jacobian = true);

}  // namespace gen4d::diagnose
