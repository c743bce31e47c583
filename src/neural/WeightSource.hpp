//! Where the solver gets NeuralMTL weights: a file named by the deck, or a generator that
//! programs built with LibTorch install (the diffusion generator plus fine-tuning, cached).
#pragma once

#include <functional>
#include <memory>
#include <string>

#include "neural/NeuralMtl.hpp"
#include "parallel/Comm.hpp"

namespace gen4d::neural {

//! Produces weights for (law, nu); E is passed for the record (psi/E does not depend on it).
using WeightGenerator =
    std::function<NeuralMtlWeights(const std::string& law, double nu, double youngs_modulus)>;

//! Installs the generator used when a deck names no weight file (empty function: none).
void set_weight_generator(WeightGenerator generator);

//! Loads the network for a deck on every rank of `comm`: reads `file` when it is not empty,
//! otherwise rank 0 runs the installed generator and broadcasts the weights. Checks that the
//! weights were fitted for `law` and nu (within 5e-4); InputError naming the file or the
//! missing generator otherwise, raised on every rank.
std::unique_ptr<NeuralMtl> load_network(MPI_Comm comm, const std::string& file,
                                        const std::string& law, double nu, double youngs_modulus);

}  // namespace gen4d::neural
