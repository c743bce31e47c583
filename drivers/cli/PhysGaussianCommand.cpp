#include "cli/PhysGaussianCommand.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <vector>

#include "core/Error.hpp"
#include "core/Log.hpp"
#include "gaussians/Camera.hpp"
#include "gaussians/PhysGaussianConfig.hpp"
#include "gaussians/PhysGaussianOutput.hpp"
#include "gaussians/Ply.hpp"
#include "mpm/ParticleIO.hpp"
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
  gaussians::PhysGaussianDeckFiles files;
  const fs::path cameras_path = fs::path(model_path) / "cameras.json";
  std::error_code ec;
  std::vector<gaussians::Camera> sim_cameras;
  if (fs::is_regular_file(cameras_path, ec)) {
    files.cameras = gaussians::read_cameras_json(cameras_path.string());
    if (!files.cameras.empty()) {
      files.cameras_json = "sim_cameras.json";
      sim_cameras = gaussians::cameras_to_simulation(files.cameras, pre.map);
    }
  }
  if (params.sim_area && pre.rest.size() > 0) files.scenery_ply = "scenery.ply";
  std::vector<std::string> notes;
  const std::string deck = gaussians::physgaussian_to_deck(
      params, "object.ply", pre, gaussians::PlySpace::Simulation, &notes, &files);
  const fs::path dir(out_dir);
  const std::string deck_path = (dir / "deck.toml").string();
  parallel::on_rank0(comm, out_dir + ": cannot write the converted scene", [&] {
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) throw RuntimeError(out_dir + ": cannot create directory: " + ec.message());
    gaussians::write_splats_ply((dir / "object.ply").string(), pre.selected);
    if (!files.scenery_ply.empty())
      gaussians::write_splats_ply((dir / files.scenery_ply).string(), pre.rest);
    if (!files.cameras_json.empty())
      gaussians::write_cameras_json((dir / files.cameras_json).string(), sim_cameras);
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
  log::info("physgaussian: {} Gaussians simulated, {} outside sim_area{}, {} -> {}",
            pre.selected.size(), pre.rest.size(),
            files.scenery_ply.empty() ? "" : " drawn unmoved (scenery.ply)", config, deck_path);
  for (const auto& n : notes) log::info("  note: {}", n);
  return deck_path;
}

void write_physgaussian_plys(MPI_Comm comm, const std::string& out_dir) {
  const fs::path out(out_dir);
  parallel::on_rank0(comm, out_dir + ": cannot write the particle PLYs", [&] {
    const std::string h5 = (out / "particles.h5").string();
    std::error_code ec;
    fs::create_directories(out / "simulation_ply", ec);
    if (ec) throw RuntimeError(out_dir + "/simulation_ply: cannot create: " + ec.message());
    long written = 0;
    for (const auto& frame : mpm::read_particle_frame_list(h5)) {
      const mpm::Particles p = mpm::read_particle_frame(h5, frame.index);
      // Alive particles in id order (rows of the frames file are ids).
      std::vector<std::size_t> order(p.size());
      std::iota(order.begin(), order.end(), std::size_t{0});
      std::sort(order.begin(), order.end(),
                [&](std::size_t a, std::size_t b) { return p.id[a] < p.id[b]; });
      std::vector<double> xyz;
      xyz.reserve(3 * p.size());
      for (std::size_t i : order)
        xyz.insert(xyz.end(), p.x.begin() + static_cast<std::ptrdiff_t>(3 * i),
                   p.x.begin() + static_cast<std::ptrdiff_t>(3 * i + 3));
      gaussians::write_positions_ply((out / gaussians::simulation_ply_name(frame.index)).string(),
                                     xyz);
      ++written;
    }
    log::info("physgaussian: {} particle PLYs (positions) in {}", written,
              (out / "simulation_ply").string());
  });
}

}  // namespace gen4d::cli
