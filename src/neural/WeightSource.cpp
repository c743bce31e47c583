#include "neural/WeightSource.hpp"

#include <cmath>
#include <exception>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "core/Error.hpp"
#include "core/Log.hpp"
#include "materials/Registry.hpp"
#include "parallel/Comm.hpp"

namespace gen4d::neural {
namespace {

WeightGenerator& installed() {
  static WeightGenerator generator;
  return generator;
}

void broadcast_string(MPI_Comm comm, std::string& s) {
  s = parallel::broadcast(comm, s);
}

}  // namespace

void set_weight_generator(WeightGenerator generator) {
  installed() = std::move(generator);
}

std::unique_ptr<NeuralMtl> load_network(MPI_Comm comm, const std::string& file,
                                        const std::string& law, double nu, double youngs_modulus) {
  const int rank = parallel::rank(comm);
  NeuralMtlWeights w;
  std::string error;
  std::string where = file.empty() ? "material.neural_weights (generated)" : file;
  // Rank 0 reads or generates; the others receive the architecture and the flat weights, so
  // every rank runs bit-identical networks.
  std::vector<double> flat, meta;
  if (rank == 0) {
    try {
      if (!file.empty()) {
        w = read_weights(file);
      } else {
        if (!installed())
          throw InputError(
              "material.neural_weights: not set, and this gen4d was built without LibTorch, so "
              "it cannot generate weights; run `gen4d make-material --law " +
              law + " --nu " + fmt::format("{}", nu) +
              " -o mtl.h5` on a LibTorch build and set material.neural_weights = \"mtl.h5\"");
        log::info("generating NeuralMTL weights for {} nu = {} ...", law, nu);
        w = installed()(law, nu, youngs_modulus);
        w.validate(where);
      }
      // Weights name their law as they were fitted (older files: an old spelling).
      const auto same_law = [](const std::string& a, const std::string& b) {
        return materials::canonical_law(a, materials::Solver::Voxel) ==
               materials::canonical_law(b, materials::Solver::Voxel);
      };
      if (!same_law(w.law, law) || std::fabs(w.poisson_ratio - nu) > 5e-4)
        throw InputError(
            fmt::format("{}: the weights were fitted for {} with nu = {}, but the deck asks for {} "
                        "with nu = {}",
                        where, w.law, w.poisson_ratio, law, nu));
      flat = w.flatten();
      for (int h : w.hidden()) meta.push_back(h);
    } catch (const InputError& e) {
      error = e.what();
    } catch (const std::exception& e) {
      error = where + ": " + e.what();
    }
  }
  broadcast_string(comm, error);
  if (!error.empty()) throw InputError(error);
  long sizes[2] = {static_cast<long>(meta.size()), static_cast<long>(flat.size())};
  parallel::broadcast(comm, sizes, 2);
  meta.resize(sizes[0]);
  flat.resize(sizes[1]);
  parallel::broadcast(comm, meta.data(), meta.size());
  parallel::broadcast(comm, flat.data(), flat.size());
  broadcast_string(comm, w.source);
  if (rank != 0) {
    std::vector<int> hidden(meta.begin(), meta.end());
    w = NeuralMtlWeights::architecture(hidden);
    w.law = law;
    w.poisson_ratio = nu;
    w.unflatten(flat);
  }
  if (rank == 0)
    log::info("NeuralMTL: {} nu = {}, hidden {}, {} parameters, source {}", w.law, w.poisson_ratio,
              fmt::join(w.hidden(), "x"), w.parameter_count(), w.source.empty() ? "?" : w.source);
  return std::make_unique<NeuralMtl>(w);
}

}  // namespace gen4d::neural
