//! What a diagnosis found, and its outputs: report.json, report.md, fit.csv and PNG plots.
#pragma once

#include <array>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "core/Config.hpp"
#include "diagnose/Fit.hpp"
#include "diagnose/Tuning.hpp"

namespace gen4d::diagnose {

struct ParamEstimate {
  std::string name, unit;
  double value = 0;
  double ci_lo = 0, ci_hi = 0;  //!< 95 % profile-likelihood interval
  bool ci_at_bound_lo = false, ci_at_bound_hi = false;
  //! The interval's threshold is the model's own error, not the noise's 3.84 (IntervalBasis),
  //! and holds the fit's time-step error (TimeStepCheck) ...
  bool ci_time_step = false;
  //! ... and its cells' error (the selected fit rerun on cells of h/2).
  bool ci_model_error = false;
  //! Where the threshold is not the noise's: the interval at the noise's threshold alone, on
  //! the same quadratic profiles (conditional on the model).
  double ci_noise_lo = std::numeric_limits<double>::quiet_NaN();
  double ci_noise_hi = std::numeric_limits<double>::quiet_NaN();
  //! The interval also spans a scan of the parameter's range (the fit depends on its time
  //! step, and its chi-square is rough on the scale of the step's error).
  bool ci_scanned = false;
};

//! The selected fit rerun at dt/2. The numerical check at the start measures the deck's own
//! time-step error; an effect can bring its own (a contact penalty rings at frequencies no
//! step resolves). When the fitted model's late-time motion moves by more than kTimeStepFlag
//! times the deck's (and over a noise sd), its parameters depend on dt, and two parameter
//! values are told apart only by more chi-square than the step's own error: 4/3 of the
//! dt-to-dt/2 difference over the fitted samples (second order), the threshold of the
//! profile-likelihood intervals then.
struct TimeStepCheck {
  bool done = false;
  double dispersion = std::numeric_limits<double>::quiet_NaN();  //!< noise sd, late time
  double threshold = 0;  //!< the dispersion above which the parameters depend on dt
  bool flagged = false;
  double chi2_error = std::numeric_limits<double>::quiet_NaN();  //!< the step's error
  double chi2_fit = std::numeric_limits<double>::quiet_NaN();    //!< the fit's chi-square
  long runs = 0;
};

//! A fit continued to its optimum where its refit stopped at the iteration limit
//! (kPolishRounds more fits of as many iterations at most).
struct FitContinuation {
  int rounds = 0;
  long runs = 0;
  double chi2_before = 0;  //!< the refit's, before the first continuation
  double chi2_after = 0;   //!< after the last (the refit's where none lowered it)
  std::string reason;      //!< how the last continuation ended
};

//! One refitted candidate.
struct Candidate {
  std::string effect, variant;
  double screen_gain = 0;  //!< linearised chi-square drop at screening
  bool fitted = false;
  std::vector<ParamEstimate> params;
  std::vector<double> z;  //!< internal coordinates (baseline first)
  //! The baseline's (log E, nu) at which the best screening group ran when that was not the
  //! calibrated baseline (Effect::probe_baselines): the refit starts there. Empty: calibrated.
  std::vector<double> base_start;
  double chi2 = 0;       //!< training chi-square
  int k = 0;             //!< parameters counted by BIC (continuous + discrete)
  double lrt = 0;        //!< N ln(chi2_0 / chi2)
  double delta_bic = 0;  //!< lrt - k ln N (> 0 favours the effect)
  double rms = 0, heldout_rms = 0;
  double heldout_chi2 = 0;  //!< noise-weighted, over every held-out channel (any unit)
  bool passes = false;
  std::string why;  //!< why it passed or failed the selection rules
  double youngs_modulus = 0, poisson_ratio = 0;
  Prediction pred;
  Eigen::MatrixXd J;          //!< Jacobian of the training residual at z, when the fit left one
  std::string fit_reason;     //!< how its fit ended (TAO's converged reason)
  bool fit_at_limit = false;  //!< its fit stopped at the iteration or run limit, still descending
  FitContinuation polish;     //!< its fit's continuation (selected fits only)
};

struct Signature {
  std::string name;  //!< amplitude_decay | frequency_shift | static_offset | permanent_set |
                     //!< mode_shape_change
  bool present = false;
  double value = 0;  //!< measured size (see detail)
  std::string detail;
};

//! The discretisation check: the calibrated baseline rerun on voxels of h/2 (E refitted), its
//! difference scaled to the error of the h model (4/3, second order).
struct RefinementCheck {
  bool done = false;
  std::string skipped;  //!< why it was not done (empty when done or not needed)
  double voxel_size = 0;
  std::size_t voxels = 0, channels = 0;  //!< voxels at h/2; channels measured
  double youngs_modulus = 0;             //!< E refitted at h/2
  double chi2 = 0;           //!< noise-weighted squared error summed over the scored values
  double noise_sd = 0;       //!< rms of the error in noise sd
  double rms = 0;            //!< rms of the error over position values, m
  bool upper_bound = false;  //!< E not refitted: the first pair already decided (chi2 a bound)
  bool linearised = false;   //!< E refitted by the pair's linearisation (no third run)
  //! Decided on voxels of 2h (voxel_size): the grid convergence index of the h-to-2h
  //! difference (safety factor 3) bounds the error, and no h/2 run was needed.
  bool coarse = false;
  long runs = 0;
  long failed = 0;            //!< of those runs, the failed ones (Evaluator::failed)
  std::string first_failure;  //!< the first one's reason
  double run_seconds = 0, idle_seconds = 0;
};

//! The most held-out chi-square a missing effect could explain: the calibrated baseline's
//! less the noise's share (the refit stage's misfit budget). When that is not more than
//! the discretisation check's error, no effect could be kept and none is refitted.
struct MisfitBudget {
  bool evaluated = false;  //!< the noise carries enough of the misfit for the test to pay
  double scored_chi2 = 0;  //!< the calibrated baseline's, over the scored values
  double noise_sd = 0;     //!< the noise of the baseline's residual (position), m
  double noise_chi2 = 0;   //!< the noise's share of scored_chi2 at that estimate
  double bound = 0;        //!< most an effect could explain (margins included)
  bool exhausted = false;  //!< bound <= the discretisation check's chi2: nothing refitted
};

//! The threshold of the effect parameters' profile intervals and what set it. The noise's
//! 3.84 (in units of the fit's residual variance s2) holds where the model's own error is
//! below the noise. Else the selected fit's own error sets it: rerun at dt/2 and on cells of
//! h/2 (E refitted, the part of the error E cannot absorb, 4/3 of the difference), over the
//! fitted values. A bias of the effect parameters moves chi-square by at most that error (in
//! the linear range), so values closer than it cannot be told apart by this model.
struct IntervalBasis {
  std::string from = "noise";  //!< noise | time_step_error | model_error (the larger part)
  //! The model's own error on the fitted values: the time step's (the selected fit at dt/2,
  //! 4/3 of the difference, its part along E left out where the fit does not depend on the
  //! step) and the cells' (fit_refinement); their sum over s2 is the threshold when above 3.84.
  double chi2_time_step = 0, chi2_cells = 0;
  double threshold = 3.84;  //!< chi-square above the fit, in units of s2
  double s2 = std::numeric_limits<double>::quiet_NaN();  //!< residual variance per value
  RefinementCheck fit_refinement;                        //!< the selected fit at h/2
  //! Each effect parameter's range scanned at this many values (the fit depends on its step).
  int scan_points = 0;
  long scan_runs = 0;
  //! The probes' Gauss-Newton steps of the other parameters (runs, kProfileSteps at most per
  //! probe), and how many of them lowered the probe's chi-square (a curved profile).
  long profile_runs = 0, profile_lowered = 0;
  //! Probes placed again nearer the threshold's crossing (each one profile point more).
  long profile_refines = 0;
};

struct Diagnosis {
  std::string deck, recording;
  std::string model = "voxel";  //!< the forward model: voxel | mpm
  //! Effects of the library the forward model does not represent, with the reason.
  std::vector<std::pair<std::string, std::string>> effects_left_out;
  std::string verdict = "none";  //!< missing_physics | none | ambiguous
  std::string effect;            //!< empty: null
  std::string variant;
  std::vector<ParamEstimate> effect_parameters;
  double youngs_modulus = 0, poisson_ratio = 0, density = 0;
  double youngs_nominal = 0, poisson_nominal = 0;
  bool poisson_held = false;  //!< nu held at the deck's (--hold-poisson)
  //! The fitted values hold one measured series (one axis of one sensor): it sees no lateral
  //! contraction, so a fitted nu trades with E (a thin strip's plate stiffness E / (1 - nu^2)).
  bool one_series = false;
  std::vector<ParamEstimate> baseline_ci;
  //! The release state fitted with E (a deck with pre-loads): preload_scale, time_offset (s).
  std::vector<ParamEstimate> release;
  //! The two lowest modal frequencies (Hz) of the recording and of the final fit's prediction
  //! after the last load change (0: none stands out of the noise), and the final fit's modal
  //! damping ratios of those modes where it has Rayleigh damping (NaN otherwise).
  std::array<double, 2> modes_measured{{0, 0}}, modes_fitted{{0, 0}};
  std::array<double, 2> modal_damping{
      {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN()}};
  bool has_region = false;
  BoxRegion region;
  BoxRegion located_region;  //!< from the sensitivity map (even when not selected)
  bool located = false;
  std::vector<std::pair<double, double>> time_windows;
  std::vector<std::string> window_phase;
  std::vector<std::string> markers;
  double rms_nominal = 0, rms_before = 0, rms_after = 0;
  double heldout_rms_nominal = 0, heldout_rms_before = 0, heldout_rms_after = 0;
  std::string runner_up;
  double runner_up_heldout = 0, runner_up_bic = 0;
  //! Vuong's z of the winner against a passing runner-up (NaN without one).
  double vuong_z = std::numeric_limits<double>::quiet_NaN();
  //! Runner-up's held-out chi2 minus the winner's, over the winner's held-out chi2 minus its
  //! count (the misfit it leaves beyond the noise); ambiguous below 1.
  double runner_up_gap = std::numeric_limits<double>::quiet_NaN();
  //! Effects refitted beyond the screening's first few because the best refit left far more
  //! misfit than the noise and the cells account for (empty: none).
  std::vector<std::string> deeper_refits;
  //! The selected effect's fit continued to its optimum (Candidate::polish of the selected).
  FitContinuation polish;
  double noise_position = 0, noise_acceleration = 0;
  //! The recording's own noise estimate of the markers (local cubics), before the calibrated
  //! residual's.
  double noise_recording_position = 0, noise_recording_acceleration = 0;
  //! The same estimate on the residual of the fitted model (the selected effect's refit, else
  //! the calibrated baseline): where an effect was missing, the calibrated residual still holds
  //! its motion, which the cubics count as noise (NaN where there are no such channels).
  double noise_fitted_position = std::numeric_limits<double>::quiet_NaN();
  double noise_fitted_acceleration = std::numeric_limits<double>::quiet_NaN();
  double chi2_red = 0, whiteness_p = 1, lag1 = 0;
  bool misfit = false;
  double dt = 0, numerical_change = 0;  //!< amplitude change of the dt/2 rerun, noise units
  double numerical_dispersion = 0;      //!< late-time rms difference of the dt/2 rerun
  bool dt_halved = false;
  TimeStepCheck time_step;
  RefinementCheck refinement;
  IntervalBasis intervals;
  MisfitBudget budget;
  std::vector<Signature> signatures;
  std::vector<Candidate> candidates;  //!< screened (gain) and refitted ones
  std::string ambiguity_experiment;
  std::vector<std::string> contenders;  //!< the two effects an ambiguous verdict cannot separate
  std::string unexplained;
  long runs = 0;
  long runs_reused = 0;       //!< runs asked for again and taken from the evaluator's memo
  long failed_runs = 0;       //!< forward runs that failed (Evaluator::failed)
  std::string first_failure;  //!< the first failed run's reason
  long continued_runs = 0;    //!< runs with StVK's stress continued (Evaluator::continued)
  double wall_seconds = 0, run_seconds = 0;
  double idle_seconds = 0;  //!< rank seconds in batches of runs not spent running (Evaluator)
  //! Forward runs and wall seconds by phase of the method, in order.
  struct Phase {
    std::string name;
    long runs = 0;
    double wall_seconds = 0;
  };
  std::vector<Phase> phases;
  int ranks = 1;
  // plotting data
  std::vector<double> bin_t, bin_e_before, bin_e_after;  //!< residual energy per time bin
  std::vector<std::string> channel_ids;
  std::vector<Vec3d> channel_X;
  std::vector<double> channel_rms_before, channel_rms_after;
  std::vector<Vec3d> block_center;
  std::vector<double> block_gain;
  Prediction baseline_pred, fitted_pred;
  BoxRegion body;
  //! Every channel is an accelerometer: rms values and noise are accelerations (Fit's rms()).
  bool accelerations_only = false;
};

//! A thin body's bending identifies E t^2 / rho, not E (t: its thinnest extent). Set
//! (`thin`) when the body's bounding box is at least kThinAspect times longer than thick.
struct ThinBody {
  bool thin = false;
  int long_axis = 0, thin_axis = 0;
  double length = 0, thickness = 0;
  //! The thickness at which the deck's E gives the calibrated E t^2 (same frequencies).
  double equivalent_thickness = 0;
};
constexpr double kThinAspect = 20;
ThinBody thin_body(const Diagnosis& d);

//! The unit of the report's rms values and residuals: positions (m) when the recording has any
//! marker, else accelerations (m/s^2), as rms() measures them.
inline const char* value_unit(const Diagnosis& d) {
  return d.accelerations_only ? "m/s^2" : "m";
}
//! The noise sd of the values in value_unit().
inline double value_noise(const Diagnosis& d) {
  return d.accelerations_only ? d.noise_acceleration : d.noise_position;
}

//! The discretisation check puts the model's own error above kEffectiveAboveNoise noise sd.
inline bool model_error_dominates(const Diagnosis& d) {
  return d.refinement.done && d.refinement.noise_sd > kEffectiveAboveNoise;
}

//! Writes report.json, report.md, fit.csv and the PNGs into dir (rank 0 only).
void write_reports(const std::string& dir, const Diagnosis& d, const Observations& obs);

}  // namespace gen4d::diagnose
