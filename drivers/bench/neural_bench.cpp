// bench_neural — the fused NeuralMTL kernel against LibTorch on one core.
//
// Sample runs:
//   build/drivers/bench_neural                         (random 24,24 network, 2^16 points)
//   build/drivers/bench_neural --weights mtl.h5 --points 4096 --seconds 0.2
//
// Description:
//   1. One batch of deformations (the training sampler), one network (--weights, or random
//      weights of the --hidden architecture), single thread for both sides.
//   2. Time neural::NeuralMtl::evaluate (energy + gradient) and ::strain (forward only)
//      against LibTorch's forward pass under no_grad and forward + autograd gradient; each is
//      repeated until --seconds have passed.
//   3. Print JSON: evaluations per second per core, the speedups, and the largest relative
//      differences between the two sides (the fused kernel must match to 1e-6, else exit 1).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "neural/NeuralMtl.hpp"
#include "neural_train/Train.hpp"
#include "validation/DriverCommon.hpp"

using namespace gen4d;
namespace nt = gen4d::neural_train;

namespace {

struct Options {
  std::string weights, hidden = "24,24";
  long points = 1L << 16;
  double seconds = 1.0;
};

double rate(long points, double min_seconds, const std::function<void()>& f) {
  f();  // warm-up
  long reps = 0;
  const auto t0 = std::chrono::steady_clock::now();
  double el = 0;
  do {
    f();
    ++reps;
    el = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  } while (el < min_seconds);
  return static_cast<double>(reps) * static_cast<double>(points) / el;
}

double max_rel(const std::vector<double>& a, const std::vector<double>& b) {
  double scale = 0, worst = 0;
  for (double v : b) scale = std::max(scale, std::fabs(v));
  for (std::size_t i = 0; i < a.size(); ++i)
    worst = std::max(worst, std::fabs(a[i] - b[i]) / std::max(std::fabs(b[i]), 1e-9 * scale));
  return worst;
}

int run(const Options& o) {
  nt::set_threads(1);
  neural::NeuralMtlWeights w;
  if (!o.weights.empty()) {
    w = neural::read_weights(o.weights);
  } else {
    w = neural::NeuralMtlWeights::architecture(nt::parse_hidden(o.hidden, "--hidden"));
    w.law = "neo_hookean";
    w.poisson_ratio = 0.3;
    std::mt19937_64 rng(1);
    std::normal_distribution<double> normal;
    for (auto& L : w.layers) {
      for (double& v : L.W) v = normal(rng) / std::sqrt(L.in);
      for (double& v : L.b) v = 0.1 * normal(rng);
    }
  }
  const std::size_t n = static_cast<std::size_t>(o.points);
  const std::vector<double> sigma = nt::sample_deformations(n, 77);
  const neural::NeuralMtl net(w);
  std::vector<double> psi(n), grad(3 * n), strain(3 * n), tp(n), tg(3 * n), ts(3 * n);

  const double fused_eval =
      rate(o.points, o.seconds, [&] { net.evaluate(n, sigma.data(), psi.data(), grad.data()); });
  const double fused_strain =
      rate(o.points, o.seconds, [&] { net.strain(n, sigma.data(), strain.data()); });
  const double torch_fwd = rate(o.points, o.seconds, [&] {
    nt::torch_forward(w, n, sigma.data(), nullptr, nullptr, ts.data());
  });
  const double torch_grad = rate(o.points, o.seconds, [&] {
    nt::torch_forward(w, n, sigma.data(), tp.data(), tg.data(), nullptr);
  });
  const double d_psi = max_rel(psi, tp), d_grad = max_rel(grad, tg), d_strain = max_rel(strain, ts);
  const bool ok = d_psi < 1e-6 && d_grad < 1e-6 && d_strain < 1e-6;
  std::string hidden;
  for (int h : w.hidden()) hidden += (hidden.empty() ? "" : ",") + std::to_string(h);
  std::printf(
      "{\n  \"points\": %ld,\n  \"hidden\": \"%s\",\n  \"threads\": 1,\n"
      "  \"fused_energy_gradient_per_s\": %.4e,\n  \"fused_strain_per_s\": %.4e,\n"
      "  \"torch_forward_nograd_per_s\": %.4e,\n  \"torch_forward_autograd_per_s\": %.4e,\n"
      "  \"speedup_energy_gradient\": %.2f,\n  \"speedup_forward\": %.2f,\n"
      "  \"max_rel_diff_energy\": %.3e,\n  \"max_rel_diff_gradient\": %.3e,\n"
      "  \"max_rel_diff_strain\": %.3e,\n  \"match\": %s\n}\n",
      o.points, hidden.c_str(), fused_eval, fused_strain, torch_fwd, torch_grad,
      fused_eval / torch_grad, fused_strain / torch_fwd, d_psi, d_grad, d_strain,
      ok ? "true" : "false");
  return ok ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  return driver::main_with(
      argc, argv, "Fused NeuralMTL kernel vs LibTorch, single thread",
      [&](CLI::App& app) {
        app.add_option("--weights", o.weights, "NeuralMTL weights file (default: random)")
            ->check(CLI::ExistingFile);
        app.add_option("--hidden", o.hidden, "Architecture of the random network");
        app.add_option("--points", o.points, "Batch size")->check(CLI::Range(8L, 1L << 24));
        app.add_option("--seconds", o.seconds, "Minimum time per measurement");
      },
      [&] {
        int rank = 0;
        MPI_Comm_rank(MPI_COMM_WORLD, &rank);
        return rank == 0 ? run(o) : 0;
      });
}
