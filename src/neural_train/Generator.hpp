//! The NeuralMTL weight generator (seed App. B): a dataset of fitted networks over (law, nu),
//! an autoencoder from flattened weights to a latent vector and a conditional DDPM in that
//! latent space. Torch-free interface; the models live in Generator.cpp.
//
// E is not a condition: psi/E of every supported law depends on nu only (the energy is linear
// in E at fixed nu), so one network per (law, nu) serves every E and the generator is
// conditioned on the law (one-hot) and nu.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "neural/NeuralMtl.hpp"

namespace gen4d::neural_train {

inline constexpr const char* kDatasetFormat = "gen4d-mtl-dataset";
inline constexpr const char* kGeneratorFormat = "gen4d-mtl-generator";
inline constexpr long kGeneratorVersion = 1;

//! Fitted networks of one architecture, in the order they were fitted.
struct WeightDataset {
  std::vector<int> hidden;
  std::vector<int> law;  //!< index into neural::neural_laws()
  std::vector<double> nu;
  std::vector<std::vector<double>> weights;  //!< NeuralMtlWeights::flatten()
  std::vector<double> fit_error, correlation, stress_median, stress_p99;
  double seconds = 0;  //!< time the fits took
  std::size_t size() const { return nu.size(); }
};

struct DatasetOptions {
  int nu_count = 25;  //!< nu values per law, evenly spaced in [0, nu_max]
  double nu_max = 0.49;
  std::vector<int> hidden{24, 24};
  int first_steps = 4000;  //!< Adam iterations of the first (cold) fit
  int first_lbfgs = 1500;
  int switch_steps = 1000;  //!< Adam iterations where the chain changes law
  int switch_lbfgs = 800;
  int steps = 0;  //!< Adam iterations of each warm-started fit (L-BFGS alone does better)
  int lbfgs_steps = 400;
  std::uint64_t seed = 1;
  bool progress = true;
};

//! The fitting order: corotated with nu rising, neo_hookean falling, stvk rising, so that
//! every fit warm-starts from its neighbour in one chain (seed Fig. 2b) and the weights are a
//! smooth function of the condition.
std::vector<std::pair<int, double>> dataset_chain(int nu_count, double nu_max);

WeightDataset build_dataset(const DatasetOptions& options);
void write_dataset(const std::string& path, const WeightDataset& d);
//! InputError naming the file on a missing, corrupt or inconsistent file.
WeightDataset read_dataset(const std::string& path);

struct GeneratorOptions {
  int latent = 64;
  int ae_hidden = 128;
  int ae_steps = 4000;
  double ae_latent_noise = 0.01;  //!< latent noise while training the decoder (robustness)
  int ddpm_hidden = 192;
  int ddpm_steps = 30000;
  int ddpm_batch = 128;
  int timesteps = 200;  //!< T, cosine schedule
  std::uint64_t seed = 1;
  bool progress = true;
};

struct GeneratorReport {
  double ae_seconds = 0, ddpm_seconds = 0;
  double ae_rms = 0;       //!< RMS AE reconstruction error in normalised weight units
  double ddpm_loss = 0;    //!< final epsilon MSE (mean of the last 500 steps)
  std::size_t values = 0;  //!< numbers stored (parameters, statistics, schedule)
};

//! Energy correlation (held-out deformations) of the dataset's networks after the AE round
//! trip, and of DDPM samples at the dataset's own conditions: min and median over the set.
struct GeneratorCheck {
  double ae_min = 0, ae_median = 0, sample_min = 0, sample_median = 0;
};
class Generator;
GeneratorCheck check_generator(const Generator& g, const WeightDataset& data,
                               std::uint64_t seed = 1);

//! Trains AE then DDPM on `data` and writes the generator to `out` (one ArrayFile).
void train_generator(const WeightDataset& data, const GeneratorOptions& options,
                     const std::string& out, GeneratorReport* report = nullptr);

//! A generator read back from its file; every shape is checked against the header numbers.
class Generator {
 public:
  //! InputError naming `path` on a missing, corrupt, wrong-format or inconsistent file.
  static Generator load(const std::string& path);
  ~Generator();
  Generator(Generator&&) noexcept;
  Generator& operator=(Generator&&) noexcept;

  const std::vector<int>& hidden() const;
  //! DDPM ancestral sampling in latent space (deterministic for a seed), then decoding.
  neural::NeuralMtlWeights sample(int law, double nu, std::uint64_t seed) const;
  //! Encode then decode (the autoencoder's round trip) of a flattened network.
  std::vector<double> reconstruct(const std::vector<double>& flat) const;
  //! The conditions of the training set: (law, nu) pairs.
  std::vector<std::pair<int, double>> trained_conditions() const;

 private:
  friend void train_generator(const WeightDataset&, const GeneratorOptions&, const std::string&,
                              GeneratorReport*);
  struct Impl;
  explicit Generator(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace gen4d::neural_train
