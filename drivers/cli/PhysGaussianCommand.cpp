#include "cli/PhysGaussianCommand.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <vector>

#include "core/Error.hpp"
#include "core/Log.hpp"
#include "gaussians/PhysGaussianConfig.hpp"
#include "gaussians/Ply.hpp"
#include "parallel/Collective.hpp"

namespace gen4d::cli {

namespace fs = std::filesystem;

std::string physgaussian_model_ply(const std::string& model_path) {
  const fs::path root = fs::path(model_path) / "point_cloud";
  std::error_code ec;
  if (!fs::is_directory(root, ec))
    throw InputError(
        fmt::format("--model-path {}: no point_cloud/ folder (a trained 3DGS model "
                    "holds point_cloud/iteration_N/point_cloud.ply)",
                    model_path));
  long best = -1;
  for (const auto& entry : fs::directory_iterator(root, ec)) {
    const std::string name = entry.path().filename().string();
    const std::string head = "iteration_";
    if (name.rfind(head, 0) != 0 || name.size() == head.size() || name.size() > head.size() + 12)
      continue;
    const std::string digits = name.substr(head.size());
    if (!std::all_of(digits.begin(), digits.end(),
                     [](unsigned char c) { return std::isdigit(c) != 0; }))
      continue;
    if (fs::is_regular_file(entry.path() / "point_cloud.ply", ec))
      best = std::max(best, std::stol(digits));
  }
  if (best < 0)
    throw InputError(
        fmt::format("--model-path {}: no point_cloud/iteration_N/point_cloud.ply", model_path));
  return (root / fmt::format("iteration_{}", best) / "point_cloud.ply").string();
}

std::string convert_physgaussian(MPI_Comm comm, const std::string& config,
                                 const std::string& model_path, const std::string& out_dir) {
  // Every rank reads and checks, so a bad input is an InputError everywhere before any write.
  const gaussians::PhysGaussianParams params = gaussians::read_physgaussian_config(config);
  const std::string ply = physgaussian_model_ply(model_path);
  const gaussians::PhysGaussianPreprocessed pre =
      gaussians::preprocess_physgaussian(gaussians::read_splats_ply(ply), params);
  std::vector<std::string> notes;
  const std::string deck = gaussians::physgaussian_to_deck(params, "object.ply", pre,
                                                           gaussians::PlySpace::Simulation, &notes);
  const fs::path dir(out_dir);
  const std::string deck_path = (dir / "deck.toml").string();
  parallel::on_rank0(comm, out_dir + ": cannot write the converted scene", [&] {
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) throw RuntimeError(out_dir + ": cannot create directory: " + ec.message());
    gaussians::write_splats_ply((dir / "object.ply").string(), pre.selected);
    const std::string tmp = deck_path + ".tmp";
    {
      std::ofstream out(tmp, std::ios::binary);
      out << "# Converted by gen4d from " << fs::absolute(config).lexically_normal().string()
          << "\n# and the model " << fs::absolute(ply).lexically_normal().string() << "\n";
      for (const auto& n : notes) out << "# note: " << n << "\n";
      out << deck;
      if (!out) throw RuntimeError(tmp + ": cannot write");
    }
    fs::rename(tmp, deck_path, ec);
    if (ec) throw RuntimeError(deck_path + ": cannot rename: " + ec.message());
  });
  log::info("physgaussian: {} Gaussians simulated ({} outside sim_area left out), {} -> {}",
            pre.selected.size(), pre.rest.size(), config, deck_path);
  for (const auto& n : notes) log::info("  note: {}", n);
  return deck_path;
}

}  // namespace gen4d::cli
