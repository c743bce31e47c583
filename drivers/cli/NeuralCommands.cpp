// gen4d train-material / train-generator / make-material (NeuralMTL, seed App. B).
//
// Sample runs:
//   gen4d train-material --law neo_hookean --nu 0.4 -o nh04.h5
//   gen4d train-generator --out inputs/models/generator.h5 --dataset mtl_dataset.h5
//   gen4d make-material --law stvk --E 1e5 --nu 0.33 -o stvk.h5
//
// Training is serial (rank 0; other ranks wait). Outputs are written atomically, and every
// argument is checked before any work starts, so a bad call never leaves a file behind.
#include "cli/NeuralCommands.hpp"

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <mpi.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <string>

#include "core/Error.hpp"
#include "core/Log.hpp"
#include "neural/NeuralMtl.hpp"

#ifdef GEN4D_WITH_TORCH
#include "neural_train/Generate.hpp"
#include "neural_train/Generator.hpp"
#include "neural_train/Train.hpp"
#endif

namespace gen4d::cli {
namespace fs = std::filesystem;

struct NeuralCommands::State {
  CLI::App *train = nullptr, *gen = nullptr, *make = nullptr;
  // train-material and make-material
  std::string law, out, hidden = "24,24", generator;
  double nu = 0, E = 1.0;
  int steps = 3000, lbfgs = 600, finetune = 200, candidates = 4, threads = 1;
  std::uint64_t seed = 1;
  // train-generator
  std::string gen_out = "inputs/models/generator.h5", dataset;
  int nu_count = 25, ae_steps = 4000, ddpm_steps = 30000, ddpm_hidden = 192;
  double ae_noise = 0.01;
};

NeuralCommands::NeuralCommands(CLI::App& app) : s_(std::make_unique<State>()) {
  State& s = *s_;
  s.train = app.add_subcommand(
      "train-material", "Fit a NeuralMTL to a hyperelastic law at one Poisson ratio (LibTorch)");
  s.train->add_option("--law", s.law, "corotated, neo_hookean or stvk")->required();
  s.train->add_option("--nu", s.nu, "Poisson ratio in [0, 0.5)")->required();
  s.train->add_option("--E", s.E, "Young's modulus (checked only: weights represent psi/E)");
  s.train->add_option("--hidden", s.hidden, "Hidden widths, e.g. 24,24 (at most 64 each)");
  s.train->add_option("--steps", s.steps, "Adam iterations")->check(CLI::Range(0, 10000000));
  s.train->add_option("--lbfgs-steps", s.lbfgs, "L-BFGS iterations after Adam")
      ->check(CLI::Range(0, 100000));
  s.train->add_option("--seed", s.seed, "Random seed (samples and initialisation)");
  s.train->add_option("--threads", s.threads, "LibTorch threads (results depend on it)")
      ->check(CLI::Range(1, 256));
  s.train->add_option("-o,--out", s.out, "Output weights (HDF5, gen4d-neuralmtl)")->required();

  s.gen = app.add_subcommand(
      "train-generator",
      "Fit the (law, nu) weight dataset, then the autoencoder and latent DDPM (LibTorch)");
  s.gen->add_option("--out,-o", s.gen_out, "Generator file (HDF5, gen4d-mtl-generator)");
  s.gen->add_option("--dataset", s.dataset,
                    "Dataset cache (HDF5): read when it exists, else built and written there");
  s.gen->add_option("--nu-count", s.nu_count, "Poisson ratios per law in [0, 0.49]")
      ->check(CLI::Range(2, 1000));
  s.gen->add_option("--ae-steps", s.ae_steps, "Autoencoder iterations")
      ->check(CLI::Range(1, 10000000));
  s.gen->add_option("--ae-noise", s.ae_noise, "Latent noise while training the decoder")
      ->check(CLI::Range(0.0, 1.0));
  s.gen->add_option("--ddpm-hidden", s.ddpm_hidden, "Width of the denoiser's hidden layers")
      ->check(CLI::Range(8, 1024));
  s.gen->add_option("--ddpm-steps", s.ddpm_steps, "DDPM iterations")
      ->check(CLI::Range(1, 10000000));
  s.gen->add_option("--seed", s.seed, "Random seed");
  s.gen->add_option("--threads", s.threads, "LibTorch threads (results depend on it)")
      ->check(CLI::Range(1, 256));

  s.make = app.add_subcommand("make-material",
                              "Generate a NeuralMTL for (law, E, nu) with the diffusion generator");
  s.make->add_option("--law", s.law, "corotated, neo_hookean or stvk")->required();
  s.make->add_option("--nu", s.nu, "Poisson ratio in [0, 0.5)")->required();
  s.make->add_option("--E", s.E, "Young's modulus (checked only: weights represent psi/E)");
  s.make->add_option("--finetune-steps", s.finetune, "L-BFGS steps after decoding (0: none)")
      ->check(CLI::Range(0, 100000));
  s.make
      ->add_option("--candidates", s.candidates,
                   "DDPM samples drawn; the one with the lowest loss on the true law is kept")
      ->check(CLI::Range(1, 1000));
  s.make->add_option("--generator", s.generator,
                     "Generator file (default: inputs/models/generator.h5)");
  s.make->add_option("--seed", s.seed, "Sampling seed");
  s.make->add_option("--threads", s.threads, "LibTorch threads (results depend on it)")
      ->check(CLI::Range(1, 256));
  s.make->add_option("-o,--out", s.out, "Output weights (HDF5, gen4d-neuralmtl)")->required();
}

NeuralCommands::~NeuralCommands() = default;

namespace {

// Argument checks shared by train-material and make-material, done before any work.
void check_material_args(const std::string& law, double nu, double E) {
  neural::law_index(law, "--law");
  if (!(nu >= 0.0 && nu < 0.5))
    throw InputError(fmt::format("--nu {}: the Poisson ratio must be in [0, 0.5)", nu));
  if (!(E > 0.0) || !std::isfinite(E))
    throw InputError(fmt::format("--E {}: Young's modulus must be finite and > 0", E));
}

// The output's directory must exist (the write is atomic, by rename within it).
void check_output(const std::string& out, const std::string& option) {
  if (out.empty()) throw InputError(option + ": no output file given");
  const fs::path dir = fs::absolute(fs::path(out)).parent_path();
  if (!fs::is_directory(dir))
    throw InputError(option + " " + out + ": directory " + dir.string() + " does not exist");
  if (fs::is_directory(out)) throw InputError(option + " " + out + ": is a directory");
}

#ifdef GEN4D_WITH_TORCH
void print_metrics(const neural_train::FitMetrics& m) {
  log::info(
      "held-out ({} samples): energy correlation {:.6f}, RMS log-energy error {:.2e}; relative "
      "stress error: strain >= 1e-3 median {:.2e} p99 {:.2e}, strain 1e-3..1e-2 median {:.2e} "
      "p99 {:.2e}, strain 1e-4..1e-3 median {:.2e}",
      m.count, m.correlation, m.rms_log_error, m.stress_median, m.stress_p99, m.stress_band_median,
      m.stress_band_p99, m.stress_small_median);
}
#endif

}  // namespace

int NeuralCommands::run() const {
  const State& s = *s_;
  const bool train = s.train->parsed(), gen = s.gen->parsed(), make = s.make->parsed();
  if (!train && !gen && !make) return -1;
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  if (rank != 0) return 0;  // serial tools; the other ranks only wait
#ifndef GEN4D_WITH_TORCH
  (void)check_material_args;
  (void)check_output;
  throw InputError("gen4d was built without LibTorch; install libtorch-dev and rebuild");
#else
  neural_train::set_threads(s.threads);
  if (train) {
    check_material_args(s.law, s.nu, s.E);
    check_output(s.out, "-o");
    neural_train::TrainOptions o;
    o.hidden = neural_train::parse_hidden(s.hidden, "--hidden");
    o.steps = s.steps;
    o.lbfgs_steps = s.lbfgs;
    o.seed = s.seed;
    o.progress = true;
    o.label = "train-material " + s.law;
    neural_train::TrainReport r;
    const neural::NeuralMtlWeights w = neural_train::train_material(s.law, s.nu, o, nullptr, &r);
    neural::write_weights(s.out, w);
    log::info("{} nu = {}: {} parameters, loss {:.3e} -> {:.3e} in {:.1f} s; wrote {}", s.law, s.nu,
              w.parameter_count(), r.first_loss, r.final_loss, r.seconds, s.out);
    print_metrics(r.heldout);
    return 0;
  }
  if (make) {
    check_material_args(s.law, s.nu, s.E);
    check_output(s.out, "-o");
    const std::string path =
        s.generator.empty() ? neural_train::default_generator_path() : s.generator;
    const neural::NeuralMtlWeights w =
        neural_train::generate_material(s.law, s.nu, s.E, path, s.finetune, s.seed, s.candidates);
    neural::write_weights(s.out, w);
    log::info("{} nu = {} from {} ({}); wrote {}", s.law, s.nu, path, w.source, s.out);
    print_metrics(neural_train::evaluate_fit(w, neural_train::heldout_deformations()));
    return 0;
  }
  check_output(s.gen_out, "--out");
  if (!s.dataset.empty()) check_output(s.dataset, "--dataset");
  neural_train::WeightDataset data;
  if (!s.dataset.empty() && fs::exists(s.dataset)) {
    data = neural_train::read_dataset(s.dataset);
    log::info("dataset {}: {} networks (fitted in {:.0f} s)", s.dataset, data.size(), data.seconds);
  } else {
    neural_train::DatasetOptions d;
    d.nu_count = s.nu_count;
    d.seed = s.seed;
    data = neural_train::build_dataset(d);
    log::info("dataset: {} networks fitted in {:.0f} s", data.size(), data.seconds);
    if (!s.dataset.empty()) {
      neural_train::write_dataset(s.dataset, data);
      log::info("wrote dataset cache {}", s.dataset);
    }
  }
  neural_train::GeneratorOptions g;
  g.seed = s.seed;
  g.ae_steps = s.ae_steps;
  g.ddpm_steps = s.ddpm_steps;
  g.ae_latent_noise = s.ae_noise;
  g.ddpm_hidden = s.ddpm_hidden;
  neural_train::GeneratorReport r;
  neural_train::train_generator(data, g, s.gen_out, &r);
  log::info(
      "wrote {}: autoencoder {:.0f} s (RMS reconstruction {:.2e} std), DDPM {:.0f} s (final "
      "loss {:.3e}), {} stored values",
      s.gen_out, r.ae_seconds, r.ae_rms, r.ddpm_seconds, r.ddpm_loss, r.values);
  const auto c = neural_train::check_generator(neural_train::Generator::load(s.gen_out), data);
  log::info(
      "energy correlation over the dataset's conditions: autoencoder round trip min {:.4f} "
      "median {:.4f}; DDPM samples min {:.4f} median {:.4f}",
      c.ae_min, c.ae_median, c.sample_min, c.sample_median);
  return 0;
#endif
}

}  // namespace gen4d::cli
