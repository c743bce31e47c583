//! Shared by the NeuralMTL test suites: reproducible random networks and stretches.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "neural/NeuralMtl.hpp"

namespace gen4d::test {

//! A 3 -> hidden... -> 3 network with Gaussian weights (scaled by 1.5/sqrt(fan-in), so the
//! tanh layers are neither linear nor saturated) and biases, labelled (law, nu).
inline neural::NeuralMtlWeights random_weights(unsigned seed, const std::vector<int>& hidden,
                                               const std::string& law = "neo_hookean",
                                               double nu = 0.3) {
  neural::NeuralMtlWeights w = neural::NeuralMtlWeights::architecture(hidden);
  w.law = law;
  w.poisson_ratio = nu;
  w.source = "test";
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  for (auto& L : w.layers) {
    for (double& v : L.W) v = normal(rng) * 1.5 / std::sqrt(L.in);
    for (double& v : L.b) v = 0.3 * normal(rng);
  }
  return w;
}

//! n triples of principal stretches in [e^-0.7, e^0.7], sorted in decreasing order.
inline std::vector<double> random_sigmas(std::size_t n, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-0.7, 0.7);
  std::vector<double> s(3 * n);
  for (std::size_t p = 0; p < n; ++p) {
    double v[3] = {std::exp(u(rng)), std::exp(u(rng)), std::exp(u(rng))};
    std::sort(v, v + 3, std::greater<>());
    for (int a = 0; a < 3; ++a) s[3 * p + a] = v[a];
  }
  return s;
}

}  // namespace gen4d::test
