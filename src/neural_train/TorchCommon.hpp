//! Internal to gen4d_neural_train (the two torch-including .cpp files): tensor helpers, the
//! MLP in LibTorch form, the deterministic generator and the progress line.
#pragma once

#include <ATen/CPUGeneratorImpl.h>
#include <torch/torch.h>

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "core/Progress.hpp"
#include "neural/NeuralMtl.hpp"

namespace gen4d::neural_train::detail {

inline torch::TensorOptions f64() {
  return torch::TensorOptions().dtype(torch::kFloat64);
}

//! A seeded CPU generator: every random tensor of a run draws from one of these, never from
//! LibTorch's global state.
inline at::Generator generator(std::uint64_t seed) {
  return at::detail::createCPUGenerator(seed);
}

//! Copies n x cols doubles into a new tensor.
inline torch::Tensor from_vector(const std::vector<double>& v, long rows, long cols) {
  return torch::from_blob(const_cast<double*>(v.data()), {rows, cols}, f64()).clone();
}
inline torch::Tensor from_ptr(const double* p, long rows, long cols) {
  return torch::from_blob(const_cast<double*>(p), {rows, cols}, f64()).clone();
}
inline std::vector<double> to_vector(const torch::Tensor& t) {
  const torch::Tensor c = t.detach().to(torch::kFloat64).contiguous();
  return std::vector<double>(c.data_ptr<double>(), c.data_ptr<double>() + c.numel());
}

//! Intra-op threads of every entry point (set_threads); applied before each run.
void apply_threads();

//! W0, b0, W1, b1, ...: the parameter list an optimiser takes, for per-layer weight lists.
inline std::vector<torch::Tensor> layer_parameters(const std::vector<torch::Tensor>& W,
                                                   const std::vector<torch::Tensor>& b) {
  std::vector<torch::Tensor> p;
  for (std::size_t l = 0; l < W.size(); ++l) {
    p.push_back(W[l]);
    p.push_back(b[l]);
  }
  return p;
}

//! A NeuralMTL as LibTorch parameters: W (out x in) and b (out) per layer, tanh between.
struct TorchMlp {
  std::vector<torch::Tensor> W, b;

  static TorchMlp from_weights(const neural::NeuralMtlWeights& w, bool requires_grad) {
    TorchMlp m;
    for (const neural::Layer& L : w.layers) {
      m.W.push_back(from_vector(L.W, L.out, L.in).set_requires_grad(requires_grad));
      m.b.push_back(from_vector(L.b, 1, L.out).reshape({L.out}).set_requires_grad(requires_grad));
    }
    return m;
  }
  void to_weights(neural::NeuralMtlWeights& w) const {
    for (std::size_t l = 0; l < W.size(); ++l) {
      w.layers[l].W = to_vector(W[l]);
      w.layers[l].b = to_vector(b[l]);
    }
  }
  std::vector<torch::Tensor> parameters() const { return layer_parameters(W, b); }
  //! Raw output m(x), x = sigma - 1 (rows of 3).
  torch::Tensor raw(const torch::Tensor& x) const {
    torch::Tensor h = x;
    for (std::size_t l = 0; l < W.size(); ++l) {
      h = torch::addmm(b[l], h, W[l].t());
      if (l + 1 < W.size()) h = torch::tanh(h);
    }
    return h;
  }
  //! Activated strain n(sigma) = m(sigma - 1) - m(0).
  torch::Tensor strain(const torch::Tensor& sigma) const {
    return raw(sigma - 1.0) - raw(torch::zeros({1, 3}, f64()));
  }
  //! psi_N = 1/2 |n|^2 per row.
  torch::Tensor energy(const torch::Tensor& sigma) const {
    return 0.5 * strain(sigma).pow(2).sum(1);
  }
};

//! One progress line on stderr every `interval` seconds and at the end: a bar, the
//! iteration, the loss and the remaining time.
class TrainProgress {
 public:
  TrainProgress(std::string label, long total, bool enabled, double interval = 2.0)
      : label_(std::move(label)), total_(total), enabled_(enabled), interval_(interval) {}
  void update(long it, double loss) {
    if (!enabled_) return;
    const auto now = Clock::now();
    if (it != total_ && seconds(last_, now) < interval_) return;
    last_ = now;
    const double done = total_ > 0 ? static_cast<double>(it) / static_cast<double>(total_) : 1;
    const double el = seconds(start_, now);
    const double eta = done > 0 ? el * (1 - done) / done : 0;
    const int filled = static_cast<int>(done * 20 + 0.5);
    std::fprintf(stderr, "%s [%s%s] %ld/%ld  loss %.3e  %s elapsed, ETA %s\n", label_.c_str(),
                 std::string(static_cast<std::size_t>(filled), '#').c_str(),
                 std::string(static_cast<std::size_t>(20 - filled), '.').c_str(), it, total_, loss,
                 ProgressLog::format_duration(el).c_str(),
                 ProgressLog::format_duration(eta).c_str());
    std::fflush(stderr);
  }

 private:
  using Clock = std::chrono::steady_clock;
  static double seconds(Clock::time_point a, Clock::time_point b) {
    return std::chrono::duration<double>(b - a).count();
  }
  std::string label_;
  long total_;
  bool enabled_;
  double interval_;
  Clock::time_point start_ = Clock::now(), last_ = Clock::now();
};

}  // namespace gen4d::neural_train::detail
