//! The tuned constants of `gen4d diagnose`'s pipeline, each with the reason for its value. The
//! stage that uses a constant is named in brackets.
#pragma once

#include <cstddef>

namespace gen4d::diagnose {

//! [calibrate] Upper bound of the calibrated Poisson ratio (a deck's larger nominal value is kept):
//! the voxel element locks volumetrically as nu nears 1/2, and a fit would use nu as a second
//! stiffness knob.
constexpr double kMaxPoisson = 0.45;

//! [refit, select] Practical significance: an effect must remove this share of the held-out rms. A
//! model never matches a recording to the noise (discretisation, unmodelled detail: the
//! Kennedy-O'Hagan discrepancy); a small but significant gain is that discrepancy being absorbed.
constexpr double kMinHeldoutGain = 0.20;

//! [refit] A refit is given up once its chi-square stays this many times above a passing refit's:
//! it could be neither the verdict nor an ambiguous contender.
constexpr double kAbandonFactor = 10.0;

//! [refit] A refit fitted in one go is also given up above this many times a passing refit's
//! chi-square when its rate of decrease, kept to the iteration limit, leaves it there: an ambiguous
//! contender needs a held-out chi-square below twice the winner's, and the rest is room for Vuong's
//! test.
constexpr double kCompeteFactor = 3.0;

//! [refit] Heterogeneity joins the refits when the stiffness map's best box explains this share of
//! the calibrated deck's chi-square (linearised) ...
constexpr double kRegionRefitShare = 0.2;
//! ... unless a refitted effect already lowers the noise-weighted held-out rms by this share.
constexpr double kRegionRefitBelowGain = 0.8;

//! [refit] Refits with several start regions give the best this many regions a short fit before
//! choosing where to start the full fit (the located box and the four quarters).
constexpr std::size_t kRegionStarts = 5;
//! [refit] Iterations of such a short fit (also a face move's and a hypothesis's).
constexpr int kRegionStartIterations = 3;
//! [refit] Lanes of the region race kept after the first continuation window: the two best there
//! are the two best at the end on the validation beams.
constexpr std::size_t kRaceKeep = 2;
//! [refit] Starts matched on two modal frequencies are used when the best removes at least this
//! share of the calibrated chi-square: a start in the true region's basin does.
constexpr double kRatioStartShare = 0.5;
//! [refit] Face moves of a region: the best this many moves of a round get a short fit.
constexpr std::size_t kMoveFits = 2;
//! [refit] ... unless the move's matched chi-square is above this multiple of the current box's: a
//! short fit removes at most about half, so such a move cannot pass the current box.
constexpr double kMoveFitReach = 2.0;
//! [refit] Face moves ranked by their predicted Gauss-Newton chi-square: this many take the step in
//! a forward run.
constexpr std::size_t kGnMoves = 4;
//! [refit] Iterations of each window fit of a continuation fit (continuation_fit).
constexpr int kWindowIterations = 4;
//! [refit] A refit with several start regions also starts from the deck's E and nu when the
//! calibration moved E by more than this (in log) or nu by more than that: the calibration may have
//! absorbed the region into E and nu.
constexpr double kDeckStartShiftE = 0.15, kDeckStartShiftNu = 0.05;
//! [refit] ... a deck start is kept when its run's dominant frequency is within this (in log) of
//! the recorded one: farther, no factor of that region matches the recording at the deck's E.
constexpr double kDeckStartReach = 0.1;

//! [select] The selected fit, where its refit stopped at the iteration limit, is continued this
//! many more fits at most (the iteration limit each).
constexpr int kPolishRounds = 2;
//! [select] With no effect kept, the verdict is still missing physics where what a missing effect
//! could explain of the held-out misfit exceeds this many times the model's own discretisation
//! error (twice it in rms): neither the noise nor the voxels can make it.
constexpr double kUnidentifiedFactor = 4.0;
//! [select] When the best passing refit leaves more held-out chi-square than this many times what
//! the noise and the model's own cells account for (the values' count plus the discretisation
//! check's chi-square), the next screened effects are refitted too.
constexpr double kDeeperRefitFactor = 10.0;

//! [check] The selected fit's parameters depend on dt when its late-time motion moves by more than
//! this many times the deck's own dt/2 difference (and over one noise sd): a deck's own motion
//! moves by a few noise sd, a fit ringing on ground contact by more.
constexpr double kTimeStepFlag = 4.0;
//! [check] Where the selected fit depends on its time step, each effect parameter's range is also
//! scanned at this many values (bounds included).
constexpr int kScanPoints = 6;
//! [check] The profile's Gauss-Newton steps of the other parameters at each probe: at most this
//! many, ...
constexpr int kProfileSteps = 4;
//! ... each on while the last lowered the probe's chi-square by this share of the threshold.
constexpr double kProfileGain = 0.02;
//! [check] Where a probe's profile chi-square is outside [1/2, 2] times the threshold, the profile
//! is probed again nearer the crossing, this many times at most.
constexpr int kProfileRefines = 3;

//! [discretisation check] Relative E step of the Gauss-Newton pair of finer-voxel runs.
constexpr double kPairStep = 5e-3;
//! [discretisation check] Within this many pair steps the pair's linearisation (exact to first
//! order) stands in for the refitted run: two h/2 runs instead of four.
constexpr double kLinearRefitReach = 4;
//! [misfit budget] The noise's squared norm is counted at this share of the estimated noise
//! variance: the estimate may be sqrt 2 high.
constexpr double kNoiseShare = 0.5;

//! [report] The discretisation check's error above this many noise sd rms: the model's cells are
//! coarse for the motion, and its parameters are effective values of them.
constexpr double kEffectiveAboveNoise = 3.0;

}  // namespace gen4d::diagnose
