//! LibTorch half of NeuralMTL: ground-truth laws, the deformation sampler and the fit of one
//! network to one (law, nu) (seed Eq. 9 plus a stress term). The interface is torch-free so
//! that drivers and tests including it compile fast; tensors live in Train.cpp only.
//
// Everything runs in float64 on the CPU. Runs are deterministic for a given seed: every
// random draw comes from a generator seeded with it, and the intra-op thread count is fixed
// (set_threads, default 1) so reductions always split the same way.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "neural/NeuralMtl.hpp"

namespace gen4d::neural_train {

//! Fixes LibTorch's intra-op thread count (and so the order of its reductions).
void set_threads(int threads);

//! Deformations as signed singular values, 3 per point, each triple descending.
//! A mix that covers what the solver visits (see Train.cpp): 60 % of the points have a
//! log-stretch vector of length log-uniform in [1e-4, 0.6] in a uniformly random direction
//! (small-strain stresses included), 25 % have independent log-stretches in [-0.6, 0.6], 15 %
//! are near inversion (smallest singular value uniform in [0.1, 0.55]).
std::vector<double> sample_deformations(std::size_t n, std::uint64_t seed);

//! Strain magnitude of a sample, max_i |sigma_i - 1| (used to select the small-strain ranges).
double strain_magnitude(const double sigma[3]);

//! Ground truth in LibTorch: psi(sigma)/E of `law` (index into neural::neural_laws()) at
//! F = diag(sigma), and its autograd gradient. psi and grad may be null.
void torch_law_energy(int law, double nu, std::size_t n, const double* sigma, double* psi,
                      double* grad);

//! The network in LibTorch: psi_N (may be null), autograd d psi_N/d sigma (may be null) and
//! the activated strain n(sigma) = m(sigma - 1) - m(0) (may be null), 3 per point.
void torch_forward(const neural::NeuralMtlWeights& w, std::size_t n, const double* sigma,
                   double* psi, double* grad, double* strain);

//! Accuracy of a network on held-out deformations.
struct FitMetrics {
  double correlation = 0;    //!< Pearson correlation of psi_N with psi over all samples
  double rms_log_error = 0;  //!< RMS of log(1+psi_N) - log(1+psi) (seed Table 1 "fitting error")
  double stress_median = 0;  //!< median of |g_N - g| / |g| over samples with strain >= 1e-3
  double stress_p99 = 0;     //!< 99th percentile of the same
  double stress_small_median = 0;  //!< median of the same over strains in [1e-4, 1e-3)
  double stress_band_median = 0;   //!< median over strains in [1e-3, 1e-2] (a cantilever's)
  double stress_band_p99 = 0;      //!< 99th percentile over the same band
  std::size_t count = 0;
};
//! Evaluates with the LibTorch forward pass. `sigma` from sample_deformations().
FitMetrics evaluate_fit(const neural::NeuralMtlWeights& w, const std::vector<double>& sigma);

//! The held-out deformations every report uses (its own seed, never a training seed).
const std::vector<double>& heldout_deformations();

struct TrainOptions {
  std::vector<int> hidden{24, 24};
  int steps = 3000;       //!< Adam iterations (0: none)
  int lbfgs_steps = 150;  //!< L-BFGS iterations after Adam (0: none)
  int batch = 4096;       //!< training samples (fixed set, redrawn every 500 Adam steps)
  double learning_rate = 3e-3;
  double stress_weight = 0.02;  //!< weight of the relative stress term
  std::uint64_t seed = 1;
  bool progress = false;  //!< progress lines (iteration, loss, ETA) through gen4d::log
  std::string label;      //!< prefix of the progress lines
};

struct TrainReport {
  double first_loss = 0, final_loss = 0;
  double seconds = 0;
  FitMetrics heldout;
};

//! Fits a NeuralMTL to `law` at Poisson ratio nu, from `warm_start` when given (its hidden
//! sizes must match options.hidden) or from a seeded random initialisation. The result has
//! source "train-material" and fit_error = held-out RMS log-energy error.
neural::NeuralMtlWeights train_material(const std::string& law, double nu,
                                        const TrainOptions& options,
                                        const neural::NeuralMtlWeights* warm_start = nullptr,
                                        TrainReport* report = nullptr);

//! Continues to fit `w` with L-BFGS only (the generator's fine-tuning), `steps` iterations.
neural::NeuralMtlWeights finetune_material(const neural::NeuralMtlWeights& w, int steps,
                                           std::uint64_t seed, TrainReport* report = nullptr);

//! Parses "24,24" into {24, 24}; InputError naming `where` unless 1..5 widths in [1, 64].
std::vector<int> parse_hidden(const std::string& text, const std::string& where);

}  // namespace gen4d::neural_train
