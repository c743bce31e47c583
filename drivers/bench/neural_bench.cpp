// bench_neural — the fused NeuralMTL kernel against LibTorch, per core, per rank's threads,
// over all ranks, and on the GPU.
//
// Sample runs:
//   build/drivers/bench_neural                         (random 24,24 network, 2^16 points)
//   build/drivers/bench_neural --weights mtl.h5 --points 4096 --seconds 0.2
//   OMP_NUM_THREADS=2 build/drivers/bench_neural       (1 rank x 2 threads)
//   OMP_NUM_THREADS=1 mpirun -np 2 build/drivers/bench_neural   (2 ranks x 1 thread)
//   build/drivers/bench_neural --device                (adds the GPU kernel)
//
// Description:
//   1. One batch of deformations (the training sampler), one network (--weights, or random
//      weights of the --hidden architecture).
//   2. Per core (rank 0, one thread on both sides): time neural::NeuralMtl::evaluate (energy +
//      gradient) and ::strain (forward only) against LibTorch's forward pass under no_grad
//      and forward + autograd gradient; each is repeated until --seconds have passed.
//   3. With more than one host thread per rank: the same on every thread of rank 0, LibTorch
//      with as many threads.
//   4. All ranks x all threads: each rank evaluates its share of the batch at the same time;
//      the aggregate rate (points over the slowest rank's time), for comparing 1 rank x 2
//      threads with 2 ranks x 1 thread.
//   5. --device: NeuralMtl::evaluate_device on --device-points points (the batch repeated)
//      already in GPU memory, and its largest relative difference from the CPU kernel;
//      "gpu": "skipped: <why>" without a device.
//   6. Print JSON: evaluations per second, the speedups, and the largest relative
//      differences between the fused kernel and LibTorch (must be < 1e-6, else exit 1).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "core/Device.hpp"
#include "core/ParallelFor.hpp"
#include "neural/NeuralMtl.hpp"
#include "neural_train/Train.hpp"
#include "validation/DriverCommon.hpp"
#if defined(GEN4D_CUDA)
#include "core/DeviceArray.hpp"
#endif

using namespace gen4d;
namespace nt = gen4d::neural_train;

namespace {

struct Options {
  std::string weights, hidden = "24,24";
  long points = 1L << 16;
  long device_points = 1L << 22;
  double seconds = 1.0;
  bool device = false;

  //! Declares the command-line options.
  void add(CLI::App& app) {
    app.add_option("--weights", weights, "NeuralMTL weights file (default: random)")
        ->check(CLI::ExistingFile);
    app.add_option("--hidden", hidden, "Architecture of the random network");
    app.add_option("--points", points, "Batch size")->check(CLI::Range(8L, 1L << 24));
    app.add_option("--seconds", seconds, "Minimum time per measurement");
    app.add_flag("--device", device, "Also time the GPU kernel (skipped without a GPU)");
    app.add_option("--device-points", device_points, "Batch size on the GPU")
        ->check(CLI::Range(8L, 1L << 26));
  }
};

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

double rate(long points, double min_seconds, const std::function<void()>& f) {
  f();  // warm-up
  long reps = 0;
  const double t0 = now();
  double el = 0;
  do {
    f();
    ++reps;
    el = now() - t0;
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

//! Runs f with `threads` host threads, then restores the previous count.
template <class F>
auto with_threads(int threads, F&& f) {
  const int before = exec::host_threads();
#if defined(_OPENMP)
  omp_set_num_threads(threads);
#endif
  auto out = f();
#if defined(_OPENMP)
  omp_set_num_threads(before);
#endif
  return out;
}

//! "gpu" fields of the JSON: rate and agreement of evaluate_device, or why it was skipped.
std::string gpu_section(const Options& o, const neural::NeuralMtl& net,
                        const std::vector<double>& sigma, const std::vector<double>& cpu_psi,
                        const std::vector<double>& cpu_grad) {
  if (!o.device) return "";
  if (!exec::cuda_built()) return ",\n  \"gpu\": \"skipped: built without CUDA\"";
  if (!exec::use_device()) return ",\n  \"gpu\": \"skipped: " + exec::device_description() + "\"";
#if defined(GEN4D_CUDA)
  const std::size_t n = sigma.size() / 3, m = static_cast<std::size_t>(o.device_points);
  std::vector<double> big(3 * m);
  for (std::size_t i = 0; i < 3 * m; ++i) big[i] = sigma[i % (3 * n)];
  exec::DeviceArray<double> ds, dpsi(m), dgrad(3 * m);
  ds.upload(big.data(), big.size());
  const double per_s = rate(o.device_points, o.seconds,
                            [&] { net.evaluate_device(m, ds.data(), dpsi.data(), dgrad.data()); });
  const std::size_t k = std::min(n, m);
  std::vector<double> psi(m), grad(3 * m);
  dpsi.download(psi.data(), m);
  dgrad.download(grad.data(), 3 * m);
  psi.resize(k);
  grad.resize(3 * k);
  const std::vector<double> cp(cpu_psi.begin(), cpu_psi.begin() + static_cast<long>(k)),
      cg(cpu_grad.begin(), cpu_grad.begin() + static_cast<long>(3 * k));
  char buf[512];
  std::snprintf(buf, sizeof buf,
                ",\n  \"gpu\": \"%s\",\n  \"gpu_points\": %ld,\n"
                "  \"gpu_energy_gradient_per_s\": %.4e,\n"
                "  \"gpu_max_rel_diff_energy_vs_cpu\": %.3e,\n"
                "  \"gpu_max_rel_diff_gradient_vs_cpu\": %.3e",
                exec::device_description().c_str(), o.device_points, per_s, max_rel(psi, cp),
                max_rel(grad, cg));
  return buf;
#else
  (void)net, (void)sigma, (void)cpu_psi, (void)cpu_grad;
  return "";
#endif
}

int run(const Options& o) {
  int rank = 0, ranks = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &ranks);
  const int threads = exec::host_threads();
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

  // Per core, then rank 0's threads; the other ranks wait.
  double fused_eval = 0, fused_strain = 0, torch_fwd = 0, torch_grad = 0;
  double fused_eval_t = 0, torch_grad_t = 0;
  if (rank == 0) {
    nt::set_threads(1);
    fused_eval = with_threads(1, [&] {
      return rate(o.points, o.seconds,
                  [&] { net.evaluate(n, sigma.data(), psi.data(), grad.data()); });
    });
    fused_strain = with_threads(1, [&] {
      return rate(o.points, o.seconds, [&] { net.strain(n, sigma.data(), strain.data()); });
    });
    torch_fwd = rate(o.points, o.seconds,
                     [&] { nt::torch_forward(w, n, sigma.data(), nullptr, nullptr, ts.data()); });
    torch_grad = rate(o.points, o.seconds, [&] {
      nt::torch_forward(w, n, sigma.data(), tp.data(), tg.data(), nullptr);
    });
    if (threads > 1) {
      // LibTorch's set_threads sets OpenMP's count too: ask for the threads explicitly.
      fused_eval_t = with_threads(threads, [&] {
        return rate(o.points, o.seconds,
                    [&] { net.evaluate(n, sigma.data(), psi.data(), grad.data()); });
      });
      nt::set_threads(threads);
      torch_grad_t = rate(o.points, o.seconds, [&] {
        nt::torch_forward(w, n, sigma.data(), tp.data(), tg.data(), nullptr);
      });
      nt::set_threads(1);
    }
  }

  // All ranks x threads at once: each rank its contiguous share, the same repetitions.
  double reps_d = rank == 0 ? std::ceil(o.seconds * fused_eval * threads * ranks / o.points) : 0;
  MPI_Bcast(&reps_d, 1, MPI_DOUBLE, 0, MPI_COMM_WORLD);
  const long reps = std::max(1L, static_cast<long>(reps_d));
  const std::size_t b0 = n * rank / ranks, b1 = n * (rank + 1) / ranks;
  std::vector<double> my_psi(b1 - b0), my_grad(3 * (b1 - b0));
  auto share = [&] { net.evaluate(b1 - b0, sigma.data() + 3 * b0, my_psi.data(), my_grad.data()); };
  const double el = with_threads(threads, [&] {
    share();  // warm-up
    MPI_Barrier(MPI_COMM_WORLD);
    const double t0 = now();
    for (long r = 0; r < reps; ++r) share();
    return now() - t0;
  });
  double el_max = 0;
  MPI_Reduce(&el, &el_max, 1, MPI_DOUBLE, MPI_MAX, 0, MPI_COMM_WORLD);
  if (rank != 0) return 0;
  const double all_eval = static_cast<double>(reps) * static_cast<double>(n) / el_max;

  const double d_psi = max_rel(psi, tp), d_grad = max_rel(grad, tg), d_strain = max_rel(strain, ts);
  const bool ok = d_psi < 1e-6 && d_grad < 1e-6 && d_strain < 1e-6;
  std::string hidden;
  for (int h : w.hidden()) hidden += (hidden.empty() ? "" : ",") + std::to_string(h);
  std::printf(
      "{\n  \"points\": %ld,\n  \"hidden\": \"%s\",\n  \"isa\": \"%s\",\n"
      "  \"per_core\": \"rank 0, 1 thread, LibTorch 1 thread\",\n"
      "  \"fused_energy_gradient_per_s\": %.4e,\n  \"fused_strain_per_s\": %.4e,\n"
      "  \"torch_forward_nograd_per_s\": %.4e,\n  \"torch_forward_autograd_per_s\": %.4e,\n"
      "  \"speedup_energy_gradient\": %.2f,\n  \"speedup_forward\": %.2f,\n",
      o.points, hidden.c_str(), net.isa(), fused_eval, fused_strain, torch_fwd, torch_grad,
      fused_eval / torch_grad, fused_strain / torch_fwd);
  if (threads > 1)
    std::printf(
        "  \"threads\": %d,\n  \"fused_energy_gradient_per_s_threads\": %.4e,\n"
        "  \"torch_forward_autograd_per_s_threads\": %.4e,\n"
        "  \"speedup_energy_gradient_threads\": %.2f,\n",
        threads, fused_eval_t, torch_grad_t, fused_eval_t / torch_grad_t);
  std::printf(
      "  \"ranks\": %d,\n  \"threads_per_rank\": %d,\n"
      "  \"all_ranks_energy_gradient_per_s\": %.4e,\n"
      "  \"max_rel_diff_energy\": %.3e,\n  \"max_rel_diff_gradient\": %.3e,\n"
      "  \"max_rel_diff_strain\": %.3e,\n  \"match\": %s%s\n}\n",
      ranks, threads, all_eval, d_psi, d_grad, d_strain, ok ? "true" : "false",
      gpu_section(o, net, sigma, psi, grad).c_str());
  return ok ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  return driver::main_with_options<Options>(
      argc, argv, "Fused NeuralMTL kernel vs LibTorch (per core, threads, ranks, GPU)", run);
}
