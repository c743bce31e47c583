// validate_neural — accuracy of NeuralMTL networks against the true laws (seed Table 1
// "fitting error", Fig. 4a correlation), for fitted networks and for the diffusion generator.
//
// Sample runs:
//   build/drivers/validate_neural                                   (all laws, full check)
//   build/drivers/validate_neural --dataset mtl_dataset.h5 --csv neural.csv
//   build/drivers/validate_neural --laws stvk --nu 0.3 --gen-nu 0.27 --steps 600
//
// Description:
//   1. Fitted networks: for each law, nu in --nu, a network fitted by train_material
//      (warm-started along nu like the dataset), or taken from --dataset when given. Report on
//      held-out deformations (a seed no training run uses): Pearson energy correlation, RMS
//      log-energy error and the relative stress error |g_N - g|/|g| (median, 99th percentile)
//      over strains >= 1e-3, and its median over strains 1e-4..1e-3.
//   2. Generator: for each law and nu in --gen-nu (values that are not in the generator's
//      dataset): one DDPM sample, the network generate_material keeps (best of --candidates
//      samples by the true law's loss) before fine-tuning, and after --finetune-steps.
//   3. Exit 1 when a target is missed: fitted correlation >= 0.999 and median stress error
//      <= 3e-3 over strains 1e-3..1e-2 (the range of a cantilever, whose stress the solver must
//      get right to ~0.3 %); generator correlation (best of --candidates) >= 0.95 before and
//      >= 0.99 after fine-tuning.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "core/Error.hpp"
#include "core/Log.hpp"
#include "neural_train/Generate.hpp"
#include "neural_train/Generator.hpp"
#include "neural_train/Train.hpp"
#include "validation/DriverCommon.hpp"

using namespace gen4d;
namespace nt = gen4d::neural_train;

namespace {

struct Options {
  std::string laws = "corotated,neo_hookean,stvk";
  std::string nu = "0.1,0.3,0.45";
  std::string gen_nu = "0.03,0.17,0.31,0.43";
  std::string dataset, generator, csv;
  int steps = 3000, warm_steps = 0, lbfgs = 500, finetune = nt::kDefaultFinetuneSteps;
  bool skip_fitted = false, skip_generator = false;
  unsigned seed = 1;
  int candidates = nt::kDefaultCandidates;
  double min_corr = 0.999, max_stress = 3e-3, gen_before = 0.95, gen_after = 0.99;

  //! Declares the command-line options.
  void add(CLI::App& app) {
    app.add_option("--laws", laws, "Comma-separated laws");
    app.add_option("--nu", nu, "Poisson ratios of the fitted networks");
    app.add_option("--dataset", dataset, "Evaluate this dataset's networks instead")
        ->check(CLI::ExistingFile);
    app.add_option("--steps", steps, "Adam iterations of the first fit per law");
    app.add_option("--warm-steps", warm_steps,
                   "Adam iterations of the later, warm-started fits of a law");
    app.add_option("--lbfgs-steps", lbfgs, "L-BFGS iterations per fit");
    app.add_option("--generator", generator, "Generator file (default: the installed one)");
    app.add_option("--gen-nu", gen_nu, "Poisson ratios for the generator (not in its data)");
    app.add_option("--finetune-steps", finetune, "Fine-tuning steps after decoding");
    app.add_option("--candidates", candidates, "DDPM samples per material (best kept)");
    app.add_option("--seed", seed, "Sampling and fine-tuning seed of the generator part");
    app.add_flag("--skip-fitted", skip_fitted, "Only the generator part");
    app.add_flag("--skip-generator", skip_generator, "Only the fitted networks");
    app.add_option("--min-corr", min_corr, "Target: fitted correlation");
    app.add_option("--max-stress", max_stress,
                   "Target: fitted median stress error over strains 1e-3..1e-2");
    app.add_option("--csv", csv, "Write every row to this CSV file");
  }
};

std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ','))
    if (!item.empty()) out.push_back(item);
  return out;
}

std::vector<double> numbers(const std::string& s, const std::string& option) {
  std::vector<double> v;
  for (const auto& item : split(s)) {
    char* end = nullptr;
    const double x = std::strtod(item.c_str(), &end);
    if (*end != '\0' || !(x >= 0 && x < 0.5))
      throw InputError(option + ": '" + item + "' is not a Poisson ratio in [0, 0.5)");
    v.push_back(x);
  }
  return v;
}

int run(const Options& o) {
  nt::set_threads(1);
  std::vector<int> laws;
  for (const auto& l : split(o.laws)) laws.push_back(neural::law_index(l, "--laws"));
  std::ofstream csv;
  if (!o.csv.empty()) {
    csv.open(o.csv);
    if (!csv) throw InputError("--csv " + o.csv + ": cannot write");
    csv << "kind,law,nu,correlation,rms_log_error,stress_median,stress_p99,stress_small_median,"
           "stress_band_median,stress_band_p99,seconds\n";
  }
  auto row = [&](const char* kind, int law, double nu, const nt::FitMetrics& m, double sec) {
    if (csv)
      csv << kind << ',' << neural::neural_laws()[law] << ',' << nu << ',' << m.correlation << ','
          << m.rms_log_error << ',' << m.stress_median << ',' << m.stress_p99 << ','
          << m.stress_small_median << ',' << m.stress_band_median << ',' << m.stress_band_p99 << ','
          << sec << '\n';
  };
  const auto& held = nt::heldout_deformations();
  int missed = 0;

  if (!o.skip_fitted) {
    nt::WeightDataset data;
    if (!o.dataset.empty()) data = nt::read_dataset(o.dataset);
    std::printf("\nFitted networks (held-out %zu deformations%s)\n", held.size() / 3,
                o.dataset.empty() ? "" : ", from the dataset");
    std::printf("%-12s %6s %10s %10s %10s %10s %10s %10s %10s %7s\n", "law", "nu", "corr",
                "fit error", "stress med", "p99", "1e-3..-2", "p99", "<1e-3 med", "s");
    for (int law : laws) {
      const std::string& name = neural::neural_laws()[law];
      neural::NeuralMtlWeights prev;
      bool have_prev = false;
      std::vector<double> nus = numbers(o.nu, "--nu");
      if (!o.dataset.empty()) {
        nus.clear();
        for (std::size_t i = 0; i < data.size(); ++i)
          if (data.law[i] == law) nus.push_back(data.nu[i]);
      }
      for (double nu : nus) {
        neural::NeuralMtlWeights w;
        double sec = 0;
        if (!o.dataset.empty()) {
          w = neural::NeuralMtlWeights::architecture(data.hidden);
          for (std::size_t i = 0; i < data.size(); ++i)
            if (data.law[i] == law && data.nu[i] == nu) w.unflatten(data.weights[i]);
          w.law = name;
          w.poisson_ratio = nu;
        } else {
          nt::TrainOptions t;
          t.steps = have_prev ? o.warm_steps : o.steps;
          t.lbfgs_steps = o.lbfgs;
          t.learning_rate = have_prev ? 1e-3 : 3e-3;
          nt::TrainReport r;
          w = nt::train_material(name, nu, t, have_prev ? &prev : nullptr, &r);
          sec = r.seconds;
          prev = w;
          have_prev = true;
        }
        const nt::FitMetrics m = nt::evaluate_fit(w, held);
        const bool ok = m.correlation >= o.min_corr && m.stress_band_median <= o.max_stress;
        missed += ok ? 0 : 1;
        std::printf("%-12s %6.3f %10.6f %10.2e %10.2e %10.2e %10.2e %10.2e %10.2e %7.1f%s\n",
                    name.c_str(), nu, m.correlation, m.rms_log_error, m.stress_median, m.stress_p99,
                    m.stress_band_median, m.stress_band_p99, m.stress_small_median, sec,
                    ok ? "" : "  MISSED");
        row("fitted", law, nu, m, sec);
      }
    }
  }

  if (!o.skip_generator) {
    const std::string path = o.generator.empty() ? nt::default_generator_path() : o.generator;
    const nt::Generator g = nt::Generator::load(path);
    if (!o.dataset.empty()) {
      const nt::GeneratorCheck c = nt::check_generator(g, nt::read_dataset(o.dataset));
      std::printf(
          "\nGenerator %s at the dataset's own conditions: energy correlation after the "
          "autoencoder round trip min %.4f median %.4f; DDPM samples min %.4f median %.4f\n",
          path.c_str(), c.ae_min, c.ae_median, c.sample_min, c.sample_median);
    }
    std::printf(
        "\nGenerator %s: nu not in its dataset; energy correlation of one DDPM sample, of the "
        "best of %d (generate_material), and after %d fine-tuning steps\n",
        path.c_str(), o.candidates, o.finetune);
    std::printf("%-12s %6s %9s %9s %9s %10s %10s %10s %10s %6s\n", "law", "nu", "1 sample",
                "best-of", "tuned", "fit error", "stress med", "p99", "1e-3..-2", "s");
    for (int law : laws)
      for (double nu : numbers(o.gen_nu, "--gen-nu")) {
        for (const auto& [cl, cn] : g.trained_conditions())
          if (cl == law && std::fabs(cn - nu) < 1e-9)
            log::warn("nu = {} is in the generator's dataset for this law", nu);
        const auto t0 = std::chrono::steady_clock::now();
        const nt::FitMetrics m1 = nt::evaluate_fit(g.sample(law, nu, o.seed), held);
        const neural::NeuralMtlWeights before = nt::generate_material(
            neural::neural_laws()[law], nu, 1.0, path, 0, o.seed, o.candidates);
        const nt::FitMetrics mb = nt::evaluate_fit(before, held);
        const neural::NeuralMtlWeights after = nt::finetune_material(before, o.finetune, o.seed);
        const nt::FitMetrics ma = nt::evaluate_fit(after, held);
        const double sec =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        const bool ok = mb.correlation >= o.gen_before && ma.correlation >= o.gen_after;
        missed += ok ? 0 : 1;
        std::printf("%-12s %6.3f %9.6f %9.6f %9.6f %10.2e %10.2e %10.2e %10.2e %6.1f%s\n",
                    neural::neural_laws()[law].c_str(), nu, m1.correlation, mb.correlation,
                    ma.correlation, ma.rms_log_error, ma.stress_median, ma.stress_p99,
                    ma.stress_band_median, sec, ok ? "" : "  MISSED");
        row("generator_1_sample", law, nu, m1, 0);
        row("generator", law, nu, mb, 0);
        row("generator+finetune", law, nu, ma, sec);
      }
  }
  std::printf("\n%s: %d case(s) missed a target\n", missed ? "FAIL" : "PASS", missed);
  return missed ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  return driver::main_with_options<Options>(
      argc, argv, "NeuralMTL accuracy: fitted networks and generator outputs vs the true laws", run,
      driver::RankZero);
}
