//! One candidate's refit (stage refit): its problem, its start and the starts it races. Shared by
//! Refit.cpp (the candidate's fit), RefitStarts.cpp (the starts of an effect that moves a
//! frequency) and RefitBox.cpp (a heterogeneity box refined by face moves).
#pragma once

#include <cstddef>
#include <limits>
#include <vector>

#include "diagnose/Pipeline.hpp"

namespace gen4d::diagnose {

//! A region and start of an effect's refit.
struct Hypothesis {
  BoxRegion region;
  std::vector<double> z;
  double start_chi2 = 0;
};

//! A candidate's refit in progress.
struct RefitWork {
  Candidate c;
  const Effect* e = nullptr;
  std::vector<ParamSpec> specs;
  LsqProblem pr;
  std::vector<double> nulls;  //!< the parameters' null values
  double z_null = 0;          //!< the first parameter's null value, internal coordinate
  //! kCompeteFactor times the best passing fit's chi-square (the one-go fit's bar).
  double compete = std::numeric_limits<double>::infinity();
  std::vector<double> z0;              //!< the start (baseline first)
  std::vector<double> grid;            //!< the effect's frequency grid (empty: moves no frequency)
  bool continued = false;              //!< fitted by continuation in time already (short fits)
  std::vector<Hypothesis> hypotheses;  //!< regions and starts on either side of the null
};

//! The starts of a refit that moves a frequency, by region.
struct StartSet {
  std::vector<BoxRegion> regions;  //!< the located box first, then the effect's start regions
  bool located_is_start = false;   //!< the located box is one of the start regions
  BoxRegion located;
  double w_cal = 0;  //!< the calibrated deck's dominant frequency
  std::vector<std::vector<double>> starts;
  std::vector<std::size_t> start_region;
  std::vector<Prediction> probe_s;  //!< the grid starts' runs
  //! Deck starts (the deck's E and nu, the factor matched to the recorded frequency).
  std::vector<std::vector<double>> deck_z;
  std::vector<std::size_t> deck_region;
  //! Starts at the recorded ratio of the two modal frequencies; the first n_crossing are crossings
  //! (run already: crossing_runs), the rest grid starts of regions without one.
  std::vector<std::vector<double>> matched;
  std::vector<std::size_t> matched_region;
  std::size_t n_crossing = 0;
  std::vector<Prediction> crossing_runs;
  //! Crossing starts the gate turned away: they join the race as lanes of their own.
  std::vector<std::vector<double>> race_crossings;
  std::vector<std::size_t> race_crossing_region;
};

//! Refits screened[i] jointly with the baseline and appends it to s.variant_fits.
void refit_one(State& s, std::size_t i);
//! The start of a refit whose effect moves a frequency (w.z0, ctx.region; w.hypotheses and
//! w.continued where it raced regions).
void frequency_starts(State& s, RefitWork& w);
//! The starts at the recorded ratio of the two modal frequencies, into S (RefitRace.cpp).
void ratio_starts(State& s, RefitWork& w, StartSet& S);
//! The start chosen from S: w.z0 and ctx.region, or w.hypotheses (RefitRace.cpp).
void pick_start(State& s, RefitWork& w, StartSet& S);
//! Refines the heterogeneity box (s.ctx.region) of the fit r by face moves.
void refine_box(State& s, RefitWork& w, LsqResult& r);
//! A run's two modal frequencies (omega2 searched near the recording's), at zp.
ModePoint mode_point(const State& s, const Prediction& p, double zp);
//! One secant step of z (log E, nu, effect parameter...) from a run measured at mp onto the
//! recorded ratio and omega1, with the slopes of x; the parameter step is at most 0.5.
void secant_correct(const State& s, std::vector<double>& z, const ModePoint& mp, const Crossing& x,
                    const LsqProblem& pr);

}  // namespace gen4d::diagnose
