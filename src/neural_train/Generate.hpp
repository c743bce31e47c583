//! Use of the weight generator: a NeuralMTL for a (law, E, nu) on demand, optionally cached.
//! This is the header the solver includes to generate materials on the fly.
#pragma once

#include <cstdint>
#include <string>

#include "neural/NeuralMtl.hpp"

namespace gen4d::neural_train {

//! Default steps of fine-tuning (L-BFGS iterations) after decoding.
inline constexpr int kDefaultFinetuneSteps = 200;

//! The generator used when none is named: $GEN4D_GENERATOR if set, else inputs/models/
//! generator.h5 of the source tree this build was configured from, else the installed copy
//! (<prefix>/share/gen4d/models/generator.h5). Returns the first candidate that exists, or the
//! source-tree path when none does (so the error names a sensible file).
std::string default_generator_path();

//! Default number of DDPM samples drawn per material, of which the one with the lowest
//! training loss on the true law is kept.
inline constexpr int kDefaultCandidates = 4;

//! DDPM sampling (deterministic for `seed`) of `candidates` networks -> decoding -> the one with
//! the lowest training loss on 2048 deformations of the true law -> `finetune_steps` L-BFGS
//! steps on the true law. Source "generator+finetune", or "generator" with 0 steps; fit_error is
//! the held-out RMS log-energy error. youngs_modulus is validated (> 0) but does not change the
//! weights: they represent psi/E. InputError on a bad law, nu outside [0, 0.5), E <= 0, or an
//! unreadable generator (naming the file).
neural::NeuralMtlWeights generate_material(const std::string& law, double nu, double youngs_modulus,
                                           const std::string& generator_path,
                                           int finetune_steps = kDefaultFinetuneSteps,
                                           std::uint64_t seed = 1,
                                           int candidates = kDefaultCandidates);

//! File name under `cache_dir` for the network of (law, nu) from `generator_path` with these
//! settings: law, nu (to 1e-6), steps, kDefaultCandidates, seed and a hash of the generator file's
//! size and modification time, so a regenerated generator never reuses stale networks.
std::string material_cache_path(const std::string& cache_dir, const std::string& law, double nu,
                                const std::string& generator_path,
                                int finetune_steps = kDefaultFinetuneSteps, std::uint64_t seed = 1);

//! material_cache_path()'s file when it exists and reads back, else generate_material() and
//! write it there (atomically; the directory is created). Serial: call on one rank.
neural::NeuralMtlWeights cached_material(const std::string& cache_dir, const std::string& law,
                                         double nu, const std::string& generator_path,
                                         int finetune_steps = kDefaultFinetuneSteps,
                                         std::uint64_t seed = 1);

}  // namespace gen4d::neural_train
