// LibTorch half of NeuralMTL: torch laws against the C++ materials, a tiny fit, the fused
// kernel against LibTorch's forward pass and autograd, the AE + DDPM round trip on a tiny
// synthetic dataset, and the generator's file checks.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "core/Error.hpp"
#include "neural_test_util.hpp"
#include "neural/ArrayFile.hpp"
#include "neural/NeuralMtl.hpp"
#include "neural_train/Generate.hpp"
#include "neural_train/Generator.hpp"
#include "neural_train/Train.hpp"

namespace gn = gen4d::neural;
namespace nt = gen4d::neural_train;
namespace fs = std::filesystem;

namespace {

std::string scratch(const std::string& name) {
  const fs::path d = fs::path(GEN4D_BINARY_DIR) / "tests" / "scratch" / "neural_train";
  fs::create_directories(d);
  const fs::path p = d / name;
  fs::remove_all(p);
  return p.string();
}

double rel_diff(double a, double b, double floor) {
  return std::fabs(a - b) / std::max(std::fabs(b), floor);
}

gn::NeuralMtlWeights random_weights(unsigned seed, const std::vector<int>& hidden) {
  return gen4d::test::random_weights(seed, hidden, "stvk", 0.2);
}

// The tiny fit shared by the training and kernel tests (trained once).
const gn::NeuralMtlWeights& tiny_fit(nt::TrainReport* report = nullptr) {
  static nt::TrainReport r;
  static const gn::NeuralMtlWeights w = [] {
    nt::TrainOptions o;
    o.hidden = {8, 8};
    o.steps = 300;
    o.lbfgs_steps = 30;
    o.batch = 512;
    o.learning_rate = 1e-2;
    o.seed = 3;
    return nt::train_material("corotated", 0.3, o, nullptr, &r);
  }();
  if (report) *report = r;
  return w;
}

// A synthetic weight dataset: two laws, weights a smooth function of nu.
nt::WeightDataset synthetic_dataset() {
  nt::WeightDataset d;
  d.hidden = {4};
  const std::size_t P = gn::NeuralMtlWeights::architecture(d.hidden).parameter_count();
  for (int law = 0; law < 2; ++law)
    for (int i = 0; i < 8; ++i) {
      const double nu = 0.45 * i / 7;
      std::vector<double> w(P);
      for (std::size_t k = 0; k < P; ++k)
        w[k] = std::sin(0.7 * k + law) + (law ? -1.0 : 1.0) * nu * std::cos(0.3 * k) + nu * nu;
      d.law.push_back(law);
      d.nu.push_back(nu);
      d.weights.push_back(w);
      d.fit_error.push_back(1e-4);
      d.correlation.push_back(1);
      d.stress_median.push_back(1e-3);
      d.stress_p99.push_back(1e-2);
    }
  return d;
}

nt::GeneratorOptions tiny_generator_options() {
  nt::GeneratorOptions o;
  o.latent = 8;
  o.ae_hidden = 32;
  o.ae_steps = 1500;
  o.ddpm_hidden = 64;
  o.ddpm_steps = 2500;
  o.ddpm_batch = 64;
  o.timesteps = 50;
  o.seed = 5;
  o.progress = false;
  return o;
}

// The tiny generator file (trained once).
const std::string& tiny_generator() {
  static const std::string path = [] {
    const std::string p = scratch("tiny_generator.h5");
    nt::train_generator(synthetic_dataset(), tiny_generator_options(), p);
    return p;
  }();
  return path;
}

template <class F>
void expect_input_error_naming(const std::string& file, F&& f) {
  try {
    f();
    ADD_FAILURE() << "no InputError for " << file;
  } catch (const gen4d::InputError& e) {
    EXPECT_NE(std::string(e.what()).find(file), std::string::npos) << e.what();
  }
}

}  // namespace

TEST(NeuralTrain, TorchLawsMatchCppLawEnergy) {
  const std::vector<double> sigma = nt::sample_deformations(600, 11);
  const std::size_t n = sigma.size() / 3;
  for (int law = 0; law < 3; ++law)
    for (double nu : {0.0, 0.25, 0.45, 0.49}) {
      std::vector<double> psi(n), grad(3 * n);
      nt::torch_law_energy(law, nu, n, sigma.data(), psi.data(), grad.data());
      double worst_e = 0, worst_g = 0;
      for (std::size_t i = 0; i < n; ++i) {
        double g[3];
        const double e = gn::law_energy(law, nu, &sigma[3 * i], g);
        worst_e = std::max(worst_e, rel_diff(psi[i], e, 1.0));
        for (int a = 0; a < 3; ++a)
          worst_g = std::max(worst_g, rel_diff(grad[3 * i + a], g[a], 1.0));
      }
      EXPECT_LT(worst_e, 1e-12) << gn::neural_laws()[law] << " nu " << nu;
      EXPECT_LT(worst_g, 1e-12) << gn::neural_laws()[law] << " nu " << nu;
    }
}

TEST(NeuralTrain, SamplerCoversTheSolversRange) {
  const std::vector<double> s = nt::sample_deformations(20000, 1);
  double smin = 10, smax = 0, strain_min = 1, strain_max = 0;
  std::size_t cantilever = 0;
  for (std::size_t i = 0; i < s.size() / 3; ++i) {
    EXPECT_GE(s[3 * i], s[3 * i + 1]);
    EXPECT_GE(s[3 * i + 1], s[3 * i + 2]);
    smin = std::min(smin, s[3 * i + 2]);
    smax = std::max(smax, s[3 * i]);
    const double m = nt::strain_magnitude(&s[3 * i]);
    strain_min = std::min(strain_min, m);
    strain_max = std::max(strain_max, m);
    cantilever += m >= 1e-3 && m <= 1e-2;
  }
  EXPECT_LT(smin, 0.12);
  EXPECT_GT(smin, 0.09);
  EXPECT_GT(smax, 1.7);
  EXPECT_LT(strain_min, 2e-4);
  EXPECT_GT(cantilever, 1000u);  // small strains are fitted too
  EXPECT_NE(nt::sample_deformations(10, 1), nt::sample_deformations(10, 2));
  EXPECT_EQ(nt::sample_deformations(10, 1), nt::sample_deformations(10, 1));
}

TEST(NeuralTrain, TinyFitLossDecreasesAndCorrelates) {
  nt::TrainReport r;
  const gn::NeuralMtlWeights& w = tiny_fit(&r);
  EXPECT_LT(r.final_loss, 0.01 * r.first_loss);
  EXPECT_GT(r.heldout.correlation, 0.99);
  EXPECT_EQ(w.source, "train-material");
  EXPECT_NEAR(w.fit_error, r.heldout.rms_log_error, 1e-15);
  // Same seed, same weights (fixed thread count, seeded generators).
  nt::TrainOptions o;
  o.hidden = {8, 8};
  o.steps = 20;
  o.lbfgs_steps = 0;
  o.batch = 256;
  o.seed = 9;
  EXPECT_EQ(nt::train_material("stvk", 0.1, o).flatten(),
            nt::train_material("stvk", 0.1, o).flatten());
}

TEST(NeuralTrain, FusedKernelMatchesLibTorch) {
  const std::vector<double> sigma = nt::sample_deformations(1000, 21);
  const std::size_t n = sigma.size() / 3;
  for (const gn::NeuralMtlWeights& w :
       {random_weights(1, {24, 24}), random_weights(2, {64, 32, 16}), tiny_fit()}) {
    const gn::NeuralMtl net(w);
    std::vector<double> psi(n), grad(3 * n), strain(3 * n), tp(n), tg(3 * n), ts(3 * n);
    net.evaluate(n, sigma.data(), psi.data(), grad.data());
    net.strain(n, sigma.data(), strain.data());
    nt::torch_forward(w, n, sigma.data(), tp.data(), tg.data(), ts.data());
    double scale_g = 0, scale_s = 0;
    for (std::size_t i = 0; i < 3 * n; ++i) {
      scale_g = std::max(scale_g, std::fabs(tg[i]));
      scale_s = std::max(scale_s, std::fabs(ts[i]));
    }
    double we = 0, wg = 0, ws = 0;
    for (std::size_t i = 0; i < n; ++i) {
      we = std::max(we, rel_diff(psi[i], tp[i], 1e-12));
      for (int a = 0; a < 3; ++a) {
        wg = std::max(wg, rel_diff(grad[3 * i + a], tg[3 * i + a], 1e-9 * scale_g));
        ws = std::max(ws, rel_diff(strain[3 * i + a], ts[3 * i + a], 1e-9 * scale_s));
      }
    }
    EXPECT_LT(we, 1e-6);
    EXPECT_LT(wg, 1e-6);
    EXPECT_LT(ws, 1e-6);
  }
}

TEST(NeuralTrain, DatasetChainAndFile) {
  const auto chain = nt::dataset_chain(3, 0.49);
  ASSERT_EQ(chain.size(), 9u);
  EXPECT_EQ(chain[0], std::make_pair(0, 0.0));
  EXPECT_EQ(chain[2], std::make_pair(0, 0.49));
  EXPECT_EQ(chain[3], std::make_pair(1, 0.49));  // neo_hookean continues from nu = 0.49
  EXPECT_EQ(chain[5], std::make_pair(1, 0.0));
  EXPECT_EQ(chain[6], std::make_pair(2, 0.0));
  const nt::WeightDataset d = synthetic_dataset();
  const std::string p = scratch("dataset.h5");
  nt::write_dataset(p, d);
  const nt::WeightDataset r = nt::read_dataset(p);
  EXPECT_EQ(r.hidden, d.hidden);
  EXPECT_EQ(r.law, d.law);
  EXPECT_EQ(r.nu, d.nu);
  EXPECT_EQ(r.weights, d.weights);
  expect_input_error_naming(tiny_generator(), [] { nt::read_dataset(tiny_generator()); });
}

TEST(NeuralTrain, AutoencoderAndDdpmRoundTrip) {
  const nt::WeightDataset d = synthetic_dataset();
  const nt::Generator g = nt::Generator::load(tiny_generator());
  EXPECT_EQ(g.hidden(), d.hidden);
  EXPECT_EQ(g.trained_conditions().size(), d.size());
  // Spread of the data, per coordinate on average.
  double spread = 0;
  const std::size_t P = d.weights[0].size();
  for (std::size_t k = 0; k < P; ++k) {
    double lo = 1e300, hi = -1e300;
    for (const auto& w : d.weights) {
      lo = std::min(lo, w[k]);
      hi = std::max(hi, w[k]);
    }
    spread += (hi - lo) / static_cast<double>(P);
  }
  double ae = 0, gen = 0;
  for (std::size_t i = 0; i < d.size(); ++i) {
    const std::vector<double> rec = g.reconstruct(d.weights[i]);
    const std::vector<double> smp =
        g.sample(d.law[i], d.nu[i], 7).flatten();  // at a trained condition
    for (std::size_t k = 0; k < P; ++k) {
      ae = std::max(ae, std::fabs(rec[k] - d.weights[i][k]));
      gen += std::fabs(smp[k] - d.weights[i][k]) / static_cast<double>(P * d.size());
    }
  }
  EXPECT_LT(ae, 0.1 * spread);
  EXPECT_LT(gen, 0.1 * spread);
  // Deterministic for a seed.
  EXPECT_EQ(g.sample(1, 0.2, 3).flatten(), g.sample(1, 0.2, 3).flatten());
  EXPECT_NE(g.sample(1, 0.2, 3).flatten(), g.sample(1, 0.2, 4).flatten());
  const gn::NeuralMtlWeights s = g.sample(0, 0.2, 3);
  EXPECT_EQ(s.law, "corotated");
  EXPECT_EQ(s.source, "generator");
}

TEST(NeuralTrain, BadGeneratorFilesNameTheFile) {
  const std::string good = tiny_generator();
  // Missing.
  const std::string missing = scratch("missing_generator.h5");
  expect_input_error_naming(missing, [&] { nt::Generator::load(missing); });
  expect_input_error_naming(missing, [&] { nt::generate_material("stvk", 0.3, 1e5, missing, 0); });
  // Truncated.
  const std::string cut = scratch("truncated_generator.h5");
  {
    std::ifstream in(good, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream(cut, std::ios::binary).write(bytes.data(), static_cast<long>(bytes.size() / 2));
  }
  expect_input_error_naming(cut, [&] { nt::Generator::load(cut); });
  // Wrong format: a NeuralMTL weights file.
  const std::string weights = scratch("weights_not_generator.h5");
  gn::write_weights(weights, random_weights(4, {8}));
  expect_input_error_naming(weights, [&] { nt::Generator::load(weights); });
  // Mismatched shapes: one layer, one statistic, and the header's parameter count.
  const gn::ArrayFile f = gn::read_array_file(good, nt::kGeneratorFormat, nt::kGeneratorVersion);
  auto mutated = [&](const std::string& name, auto&& change) {
    gn::ArrayFile m = f;
    change(m);
    const std::string p = scratch(name);
    gn::write_array_file(p, m);
    return p;
  };
  const std::string bad_layer = mutated("bad_layer.h5", [](gn::ArrayFile& m) {
    auto& a = m.arrays.at("dec1_W");
    a.shape = {a.shape[0] - 1, a.shape[1]};
    a.data.resize(static_cast<std::size_t>(a.shape[0] * a.shape[1]));
  });
  expect_input_error_naming(bad_layer, [&] { nt::Generator::load(bad_layer); });
  const std::string bad_stat = mutated("bad_stat.h5", [](gn::ArrayFile& m) {
    m.arrays.at("z_std").data.push_back(1.0);
    m.arrays.at("z_std").shape[0] += 1;
  });
  expect_input_error_naming(bad_stat, [&] { nt::Generator::load(bad_stat); });
  const std::string bad_params =
      mutated("bad_params.h5", [](gn::ArrayFile& m) { m.numbers.at("params") += 1; });
  expect_input_error_naming(bad_params, [&] { nt::Generator::load(bad_params); });
  const std::string bad_hidden =
      mutated("bad_hidden.h5", [](gn::ArrayFile& m) { m.text.at("hidden") = "4,x"; });
  expect_input_error_naming(bad_hidden, [&] { nt::Generator::load(bad_hidden); });
  EXPECT_NO_THROW(nt::Generator::load(good));
}

TEST(NeuralTrain, ParseHidden) {
  EXPECT_EQ(nt::parse_hidden("24,24", "--hidden"), (std::vector<int>{24, 24}));
  EXPECT_THROW(nt::parse_hidden("24,", "--hidden"), gen4d::InputError);
  EXPECT_THROW(nt::parse_hidden("65", "--hidden"), gen4d::InputError);
  EXPECT_THROW(nt::parse_hidden("8,8,8,8,8,8", "--hidden"), gen4d::InputError);
}

// The committed generator (inputs/models/generator.h5) at a nu between its dataset's
// values: the decoded network before fine-tuning, and the cache.
TEST(NeuralTrain, CommittedGeneratorAndCache) {
  const std::string path = std::string(GEN4D_SOURCE_DIR) + "/inputs/models/generator.h5";
  if (!fs::exists(path)) GTEST_SKIP() << path << " not present";
  const gn::NeuralMtlWeights w = nt::generate_material("neo_hookean", 0.3571, 1e5, path, 0, 1);
  EXPECT_EQ(w.source, "generator");
  const nt::FitMetrics m = nt::evaluate_fit(w, nt::heldout_deformations());
  EXPECT_GT(m.correlation, 0.95);
  const std::string dir = scratch("cache");
  const std::string p = nt::material_cache_path(dir, "stvk", 0.2, path, 0, 2);
  EXPECT_NE(p.find("stvk"), std::string::npos);
  const gn::NeuralMtlWeights a = nt::cached_material(dir, "stvk", 0.2, path, 0, 2);
  ASSERT_TRUE(fs::exists(p));
  const gn::NeuralMtlWeights b = nt::cached_material(dir, "stvk", 0.2, path, 0, 2);
  EXPECT_EQ(a.flatten(), b.flatten());
}
