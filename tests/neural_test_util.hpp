//! Shared by the NeuralMTL test suites: reproducible random networks.
#pragma once

#include <cmath>
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

}  // namespace gen4d::test
