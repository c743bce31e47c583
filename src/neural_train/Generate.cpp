// generate_material and its cache (no LibTorch here: the models are behind Generator).
#include "neural_train/Generate.hpp"

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <system_error>

#include <fmt/format.h>

#include "core/Error.hpp"
#include "neural_train/Generator.hpp"
#include "neural_train/Train.hpp"

namespace gen4d::neural_train {
namespace fs = std::filesystem;

std::string default_generator_path() {
  if (const char* env = std::getenv("GEN4D_GENERATOR"); env && *env) return env;
  const std::vector<std::string> candidates = {
#ifdef GEN4D_GENERATOR_SOURCE
      GEN4D_GENERATOR_SOURCE,
#endif
#ifdef GEN4D_GENERATOR_INSTALLED
      GEN4D_GENERATOR_INSTALLED,
#endif
  };
  for (const auto& c : candidates)
    if (fs::exists(c)) return c;
  return candidates.empty() ? "inputs/models/generator.h5" : candidates.front();
}

neural::NeuralMtlWeights generate_material(const std::string& law, double nu, double youngs_modulus,
                                           const std::string& generator_path, int finetune_steps,
                                           std::uint64_t seed, int candidates) {
  const int li = neural::law_index(law, "generate_material");
  if (!(nu >= 0.0 && nu < 0.5))
    throw InputError(fmt::format("generate_material: nu = {} is outside [0, 0.5)", nu));
  if (!(youngs_modulus > 0.0) || !std::isfinite(youngs_modulus))
    throw InputError(
        fmt::format("generate_material: Young's modulus {} must be > 0", youngs_modulus));
  if (finetune_steps < 0) throw InputError("generate_material: finetune_steps < 0");
  if (candidates < 1) throw InputError("generate_material: candidates < 1");
  if (!fs::exists(generator_path))
    throw InputError(generator_path +
                     ": generator file not found (make one with gen4d train-generator)");
  const Generator g = Generator::load(generator_path);
  // Best of `candidates` samples: the sampler's spread between seeds is larger than its bias,
  // so picking by the true law's loss (on deformations no report uses) is cheap and robust.
  const std::vector<double> pick = sample_deformations(2048, 0x5E1EC7);
  neural::NeuralMtlWeights w;
  double best = 0;
  for (int k = 0; k < candidates; ++k) {
    neural::NeuralMtlWeights c =
        g.sample(li, nu, seed * 1000003ULL + static_cast<std::uint64_t>(k));
    const double loss = training_loss(c, pick);
    if (k == 0 || loss < best) {
      best = loss;
      w = std::move(c);
    }
  }
  if (finetune_steps > 0) {
    w = finetune_material(w, finetune_steps, seed);
    w.source = "generator+finetune";
  } else {
    w.fit_error = evaluate_fit(w, heldout_deformations()).rms_log_error;
    w.source = "generator";
  }
  return w;
}

std::string material_cache_path(const std::string& cache_dir, const std::string& law, double nu,
                                const std::string& generator_path, int finetune_steps,
                                std::uint64_t seed) {
  std::error_code ec;
  const auto size = fs::file_size(generator_path, ec);
  const auto mtime = fs::last_write_time(generator_path, ec).time_since_epoch().count();
  const std::size_t h = std::hash<std::string>{}(fs::absolute(generator_path).string() + "|" +
                                                 std::to_string(ec ? 0 : size) + "|" +
                                                 std::to_string(ec ? 0 : mtime));
  const std::string name =
      fmt::format("mtl_{}_nu{:.6f}_ft{}_c{}_s{}_{:08x}.h5", law, nu, finetune_steps,
                  kDefaultCandidates, seed, static_cast<unsigned>(h & 0xffffffffu));
  return (fs::path(cache_dir) / name).string();
}

neural::NeuralMtlWeights cached_material(const std::string& cache_dir, const std::string& law,
                                         double nu, const std::string& generator_path,
                                         int finetune_steps, std::uint64_t seed) {
  const std::string path =
      material_cache_path(cache_dir, law, nu, generator_path, finetune_steps, seed);
  if (fs::exists(path)) {
    try {
      neural::NeuralMtlWeights w = neural::read_weights(path);
      if (w.law == law && std::fabs(w.poisson_ratio - nu) < 1e-12) return w;
    } catch (const InputError&) {
      // A damaged cache entry is regenerated below.
    }
  }
  neural::NeuralMtlWeights w =
      generate_material(law, nu, 1.0, generator_path, finetune_steps, seed);
  std::error_code ec;
  fs::create_directories(cache_dir, ec);
  if (ec) throw RuntimeError(cache_dir + ": cannot create the material cache: " + ec.message());
  neural::write_weights(path, w);
  return w;
}

}  // namespace gen4d::neural_train
