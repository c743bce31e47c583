//! `gen4d diagnose`: calibrate the deck against a recording, decide whether physics is
//! missing, locate the mismatch in time and space, screen and refit the effect library,
//! select on held-out data, and report (report.json, report.md, fit.csv, PNG plots).
#pragma once

#include <mpi.h>

#include <array>
#include <map>
#include <string>
#include <vector>

#include "core/Config.hpp"

namespace gen4d::diagnose {

struct DiagnoseOptions {
  std::vector<std::string> recordings;  //!< CSV / HDF5 files (positions, accelerometers)
  std::string out_dir;
  std::vector<std::string> effects;  //!< candidates; empty: the whole library
  double holdout = 0.25;             //!< fraction of time blocks and markers held out
  int refit = 3;                     //!< candidates refitted after screening
  int max_iterations = 10;           //!< TAO iterations per fit
};

struct Channel;
//! Noise standard deviation of recorded samples, model-free: blocks of 7 consecutive samples
//! of each channel component are fitted by a cubic in time; the median residual variance
//! (RSS / 3), corrected for the chi-square(3) median, is pooled over blocks. NaN without a
//! full block.
double estimate_noise(const std::vector<const Channel*>& channels);

//! Runs the diagnosis (collective over comm); rank 0 writes DIR. Returns the exit code.
//! Throws InputError for bad decks/recordings/options, RuntimeError when the model fails.
int run_diagnose(MPI_Comm comm, const Config& cfg, const DiagnoseOptions& opt);

}  // namespace gen4d::diagnose
