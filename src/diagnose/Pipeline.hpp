//! The stages of `gen4d diagnose` and the state they hand on. run_diagnose runs them in order:
//! observe (recording, observations, the solver's own dt check), calibrate (E and nu), locate (when
//! and where the calibrated deck misses, scene scales), screen (every effect's linearised probe),
//! refit (the best few fitted jointly with the baseline, the model's own discretisation error),
//! select (the verdict), check (the selected fit's time step and its parameters' intervals) and
//! report (signatures, cost, the files). Each stage reads what the earlier ones set in State and
//! sets its own part of it; the members are grouped by the stage that sets them.
#pragma once

#include <Eigen/Dense>
#include <array>
#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "core/Config.hpp"
#include "diagnose/Diagnose.hpp"
#include "diagnose/Effects.hpp"
#include "diagnose/Fit.hpp"
#include "diagnose/Modal.hpp"
#include "diagnose/Recording.hpp"
#include "diagnose/Report.hpp"

namespace gen4d::diagnose {

//! A diagnosis in progress. Not copied: the evaluator refers to `obs` and `model` in place.
struct State {
  State(MPI_Comm comm, const Config& cfg, const DiagnoseOptions& opt);
  State(const State&) = delete;
  State& operator=(const State&) = delete;
  MPI_Comm comm;
  const Config& cfg;
  const DiagnoseOptions& opt;
  int rank = 0, size = 1;
  std::chrono::steady_clock::time_point wall0;
  Diagnosis D;  //!< what the report says, filled stage by stage

  // observe
  std::unique_ptr<ForwardModel> model;
  std::vector<const Effect*> library;  //!< the effects the model represents (or --effects)
  Recording rec;
  Observations obs;
  std::unique_ptr<Evaluator> ev;  //!< forward runs of `model` sampled as `obs`
  long ntrain = 0;                //!< values fitted
  double N = 0;                   //!< ntrain, as a double
  Physics nominal;                //!< the deck's physics (dt halved where it must be)
  Prediction nominal_pred;
  // cost by phase: forward runs and wall time since the previous phase ended
  long phase_runs = 0;
  std::chrono::steady_clock::time_point phase_t0;

  // calibrate
  //! The release state of a deck with pre-loads ([[force]] start < 0), fitted with E and nu and
  //! then held by every effect's fit as trailing parameters (LsqProblem::tail): the pre-load's
  //! scale (log) and the model's time at the recording's t = 0. Empty without pre-loads.
  std::vector<ParamSpec> release_specs;
  std::vector<double> release_z;  //!< their values (z coordinates): the start, then the fit
  LsqProblem pb;                  //!< the baseline's problem: log E and nu (and the release state)
  std::vector<double> events;     //!< the deck's load changes
  double t_free = 0;              //!< the last load change: free motion after it
  LsqResult base;                 //!< the calibrated baseline's fit
  double chi2_0 = 0;              //!< its chi-square
  Physics calibrated;

  // locate
  double tb = 0, te = 0;  //!< the recording's span
  static constexpr int kBins = 40;
  EffectContext ctx;            //!< scene scales for the effects (ctx.region: the region)
  std::vector<double> windows;  //!< continuation windows
  ModalFrequencies modes;       //!< the recording's two lowest modal frequencies
  bool two_modes = false;       //!< a second mode above the noise
  double r_obs = 0;             //!< their ratio
  Eigen::MatrixXd Qb;           //!< orthonormal basis of the baseline's Jacobian
  double region_share = 0;      //!< chi2 share the located box explains (linearised)

  // screen
  std::vector<Candidate> screened;

  // refit
  double lnN = 0;
  std::vector<std::string> chosen;  //!< effects refitted
  std::vector<std::size_t> todo;    //!< indices into screened, in refit order
  bool has_holdout = false;
  const std::vector<char>* scored = nullptr;  //!< what score() sums
  double score0 = 0;                          //!< the baseline's score
  std::vector<Candidate> variant_fits;        //!< every refitted variant
  std::vector<std::array<double, 3>> channel_X;

  // select
  std::vector<Candidate> fits;     //!< one variant per effect
  std::vector<std::size_t> order;  //!< fits ranked
  const Candidate* best = nullptr;
  const Candidate* second = nullptr;
  std::vector<char> polished;  //!< per fit: continued once already

  // check
  Prediction half_fit;  //!< the selected fit at dt/2

  //! Records a phase of the cost: the runs and the wall time since the previous one.
  void phase_done(const std::string& name);
};

//! The stages, in the order run_diagnose runs them.
void observe(State& s);
void calibrate(State& s);
void locate(State& s);
void screen(State& s);
void refit(State& s);
void select(State& s);
void check(State& s);
void report(State& s);

// Shared by the stages (Calibrate.cpp, Locate.cpp, Screen.cpp, Refit.cpp, Select.cpp).

//! The baseline's physics at z = (log E, nu), the release state from s.release_z.
Physics base_physics(const State& s, const std::vector<double>& z);
//! Sets p's release state (load_scale, time_offset) from z[first ...] when z holds it there, else
//! from s.release_z; nothing without pre-loads.
void apply_release(const State& s, const std::vector<double>& z, std::size_t first, Physics& p);
//! The release state's parameters and start (State::release_specs, release_z), for a deck with
//! pre-loads on the voxel model; once.
void release_state(State& s);
//! Appends the release state's bounds, steps and start (LsqProblem::tail) to a problem.
void add_release(const State& s, LsqProblem& pr);
//! log E moved so that the dominant frequency of the motion p predicts becomes w_target (E ~
//! omega^2); zE unchanged when p failed.
double match_frequency(const State& s, double zE, double w_target, const Prediction& p);
//! The joint problem of the baseline (log E, nu) and one effect variant's parameters.
LsqProblem effect_problem(State& s, const Effect& e, const std::string& variant);
//! Per time bin, the mean squared weighted residual of p.
std::vector<double> bin_energy(const State& s, const Prediction& p);
//! d less its projection on the baseline's directions (Qb).
Eigen::VectorXd project(const State& s, const Eigen::VectorXd& d);
//! Per channel, the rms error of p.
std::vector<double> channel_rms(const State& s, const Prediction& p);
//! A candidate's score: its noise-weighted held-out chi-square (training, with no holdout).
double score(const State& s, const Candidate& c);
//! A candidate's fit, its scores and the selection rules' verdict on it.
void set_fit(State& s, Candidate& c, const LsqResult& r);
//! The discretisation check's phase of the cost (its fine model's runs).
void check_phase_done(State& s);

// Statistics and signal measures (Statistics.cpp).

//! Upper 0.1 % point of chi-square with k degrees of freedom (k <= 10), else Wilson-Hilferty.
double chi2_crit999(int k);
//! P(chi2_k > x) by the Wilson-Hilferty normal approximation.
double chi2_tail(double x, double k);
//! The median (NaN for none).
double median(std::vector<double> v);
//! Internal coordinate of a parameter value and back.
double to_z(const ParamSpec& s, double v);
double from_z(const ParamSpec& s, double z);
//! The rms difference of two predictions over the samples at t >= t_late, in noise sd.
double late_difference(const Observations& obs, const Prediction& a, const Prediction& b,
                       double t_late);
//! Ljung-Box whiteness of p's weighted residuals per (channel, component) series: the p-value and
//! the mean lag-1 autocorrelation.
void whiteness(const Observations& obs, const Prediction& p, double& p_value, double& lag1);
//! Dominant angular frequency of the motion y after t_from, from the mean-crossings of the position
//! channel component with the largest variance (accelerometers only when there is no marker:
//! acceleration weights the higher modes by omega^2).
double dominant_omega(const Observations& obs, const std::vector<double>& y, double t_from);
//! The axis (unit vector) of the position channel component whose recorded values vary most after
//! t_from: the direction of the motion dominant_omega reads its frequency off.
Vec3d motion_direction(const Observations& obs, double t_from);
//! The noise estimate (estimate_noise) of the residual obs - p, channel by channel, for positions
//! and accelerations (NaN where there are none).
void residual_noise(const Observations& obs, const Prediction& p, double& res_pos, double& res_acc);
//! Vuong's test of two fitted models on the values of `mask`: z > 0 favours a. Residuals are
//! correlated in time: the standard deviation comes from batch means of 10 samples.
double vuong_z(const Observations& obs, const std::vector<char>& mask, const Prediction& a,
               const Prediction& b);

//! The modal frequencies of a run at a value zp (internal coordinate) of an effect's first
//! parameter.
struct ModePoint {
  bool ok = false;
  double zp = 0, ratio = 0, log_w1 = 0;  //!< omega2 / omega1, log omega1
};

//! A value zp where the frequency ratio reaches its target, with the slopes d ratio / d zp and d
//! log omega1 / d zp of the pair of points it lies between (or past), log omega1 there, and the
//! start it becomes.
struct Crossing {
  double zp = 0, log_w1 = 0, slope_r = 0, slope_w = 0;
  std::vector<double> z;
};

//! Where the ratio of the points (a grid in zp) crosses r_target, interpolated linearly in zp; with
//! no crossing, the line through the two end points nearest to it, followed at most one grid step
//! outwards.
std::vector<Crossing> ratio_crossings(std::vector<ModePoint> pts, double r_target);

}  // namespace gen4d::diagnose
