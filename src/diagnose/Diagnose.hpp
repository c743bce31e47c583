//! `gen4d diagnose`: calibrate the deck against a recording, decide whether physics is
//! missing, locate the mismatch in time and space, screen and refit the effect library,
//! select on held-out data, and report (report.json, report.md, fit.csv, PNG plots).
#pragma once

#include <array>
#include <map>
#include <string>
#include <vector>

#include "core/Config.hpp"
#include "diagnose/Forward.hpp"
#include "parallel/Comm.hpp"

namespace gen4d::diagnose {

struct DiagnoseOptions {
  std::vector<std::string> recordings;  //!< CSV / HDF5 files (positions, accelerometers)
  std::string out_dir;
  //! Candidates; empty: the default library; {"all"}: every effect the model represents.
  std::vector<std::string> effects;
  double holdout = 0.25;    //!< fraction of time blocks and markers held out
  int refit = 3;            //!< candidates refitted after screening
  int max_iterations = 10;  //!< TAO iterations per fit
  //! Measure the model's spatial discretisation error (h/2 rerun) before keeping an effect.
  bool refinement_check = true;
  //! Value columns (x, y, z, ax, ay, az) not measured in any recording file (ReadOptions).
  std::vector<std::string> unmeasured;
  //! The recording's zero-phase low-pass cutoff (Hz; 0: none), applied to the predictions alike.
  double lowpass_hz = 0;
  //! Fit E alone, nu held at the deck's value (a known nu; a recording that cannot see it).
  bool hold_poisson = false;
};

struct Channel;
//! Noise standard deviation of recorded samples, model-free: blocks of 7 consecutive samples
//! of each channel component are fitted by a cubic in time; the median residual variance
//! (RSS / 3), corrected for the chi-square(3) median, is pooled over blocks. NaN without a
//! full block.
double estimate_noise(const std::vector<const Channel*>& channels);

struct Observations;
struct Prediction;
struct RefinementCheck;
//! The model's own spatial discretisation error (collective over comm): the calibrated
//! baseline rerun on the deck's body voxelized at voxel_size / 2, its E refitted to the h run's
//! prediction `base_pred` (one Gauss-Newton step from a pair of runs, and the match of the
//! dominant frequency after t_free; the closest of the four runs is kept), and the remaining
//! difference scaled by 4/3 (second order) to the error of the h model, in noise-weighted
//! chi-square summed over the `scored` values of obs. X: the reference point of each channel of
//! obs; channels whose point is not in the finer body are left out of the measure (those values
//! count at the mean of the measured ones). Not done (with the reason) when the deck cannot be
//! voxelized at h/2 or the run fails there. When the closer run of the first pair (E not yet
//! refitted, so an upper bound of the error) is already below decided_below, the check stops
//! there and reports that bound (upper_bound). Before any h/2 run, when decided_below > 0, the
//! baseline is run on voxels of 2h (E at the h voxels' rest frequency): the whole h-to-2h
//! difference bounds the h model's error (the two-grid convergence index, safety factor 3),
//! and when that bound is below decided_below it is reported (coarse, upper_bound) and no h/2
//! run is made. With linear_refit, E's Gauss-Newton step from the pair is not run where it
//! stays within kLinearRefitReach steps of the pair (the pair's linearisation, exact to first
//! order there, gives the refitted error: two h/2 runs instead of four).
RefinementCheck refinement_check(MPI_Comm comm, const Config& cfg, const Observations& obs,
                                 const std::vector<std::array<double, 3>>& X,
                                 const Physics& calibrated, const Prediction& base_pred,
                                 const std::vector<char>& scored, double t_free,
                                 double decided_below = 0, bool linear_refit = false);

struct MisfitBudget;
//! What a missing effect could explain at most of the calibrated baseline's misfit over the
//! `scored` values of obs (noise-weighted chi-square): that misfit less the noise's share. The
//! noise is estimated like estimate_noise, on the baseline's residual as well as on the
//! recording, and the lower of the two is taken per kind (a fitted motion no longer leaks into
//! the cubic windows); its share is counted at half that variance, less three standard
//! deviations of its spread, and three of the noise along the effect's correction are added.
//! `evaluated` when that share is at least a quarter of the misfit (otherwise the bound is far
//! above any model error and not worth a discretisation check to compare with).
MisfitBudget misfit_budget(const Observations& obs, const Prediction& base,
                           const std::vector<char>& scored);

//! Runs the diagnosis (collective over comm); rank 0 writes DIR. Returns the exit code.
//! Throws InputError for bad decks/recordings/options, RuntimeError when the model fails.
int run_diagnose(MPI_Comm comm, const Config& cfg, const DiagnoseOptions& opt);

}  // namespace gen4d::diagnose
