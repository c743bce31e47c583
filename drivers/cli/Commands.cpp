#include "cli/Commands.hpp"

#include <CLI/CLI.hpp>
#include <H5public.h>
#include <mpi.h>
#include <openvdb/version.h>
#include <petscversion.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "DefaultDeck.hpp"
#include "core/BuildInfo.hpp"
#include "core/Deck.hpp"
#include "core/Error.hpp"
#include "core/Log.hpp"
#include "elastogen/Simulation.hpp"
#include "io/Checkpoint.hpp"
#include "io/FrameReader.hpp"
#include "io/PngPreview.hpp"

namespace gen4d::cli {
namespace fs = std::filesystem;

namespace {

struct RunArgs {
  std::string deck;
  std::string out;
  std::vector<std::string> sets;
  bool overwrite = false;
};

int rank_of(MPI_Comm c) {
  int r = 0;
  MPI_Comm_rank(c, &r);
  return r;
}

//! Refuses to clobber an earlier run's results unless asked to; decided on rank 0 so every
//! rank takes the same branch.
void check_output_dir(const std::string& out, bool overwrite) {
  int exists = 0;
  if (rank_of(MPI_COMM_WORLD) == 0) exists = fs::exists(fs::path(out) / "frames.h5") ? 1 : 0;
  MPI_Bcast(&exists, 1, MPI_INT, 0, MPI_COMM_WORLD);
  if (exists && !overwrite)
    throw InputError("--out " + out +
                     ": already holds results (frames.h5); pass --overwrite to replace them or "
                     "choose another directory");
}

int run_simulation(elastogen::Simulation& sim, const std::string& out, bool append) {
  elastogen::Simulation::install_signal_handlers();
  const auto res = sim.run(out, append);
  if (res.exit_code == 0)
    log::info("done: {} steps in {:.2f} s; frames {}/frames.h5 (+ .xdmf), checkpoint {}", res.steps,
              res.wall_seconds, out, res.last_checkpoint);
  return res.exit_code;
}

int cmd_run(const RunArgs& a) {
  Config cfg = a.deck.empty() ? parse_deck(default_deck_text, "<embedded default>", ".", a.sets)
                              : load_deck(a.deck, a.sets);
  const std::string out = a.out.empty() ? cfg.output.dir : a.out;
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);  // validates geometry; writes nothing
  check_output_dir(out, a.overwrite);
  return run_simulation(sim, out, false);
}

int cmd_restart(const std::string& checkpoint, const std::string& out_arg,
                const std::vector<std::string>& sets) {
  const io::CheckpointMeta meta = io::read_checkpoint_meta(MPI_COMM_WORLD, checkpoint);
  Config cfg = parse_deck(meta.deck_text, checkpoint + " (stored deck)", ".", sets);
  const std::string out = out_arg.empty() ? fs::path(checkpoint).parent_path().string() : out_arg;
  const std::string dir = out.empty() ? "." : out;
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
  sim.load_checkpoint(checkpoint);
  int exists = 0;
  if (rank_of(MPI_COMM_WORLD) == 0) exists = fs::exists(fs::path(dir) / "frames.h5") ? 1 : 0;
  MPI_Bcast(&exists, 1, MPI_INT, 0, MPI_COMM_WORLD);
  return run_simulation(sim, dir, exists != 0);
}

std::string gpus_seen() {
  std::error_code ec;
  int n = 0;
  if (fs::exists("/proc/driver/nvidia/gpus", ec))
    for (const auto& e : fs::directory_iterator("/proc/driver/nvidia/gpus", ec)) {
      (void)e;
      ++n;
    }
  std::string s = std::to_string(n) + " NVIDIA GPU(s) visible";
  if (!build::cuda) s += "; this build has no CUDA back end (GEN4D_CUDA=OFF)";
  return s;
}

int cmd_info() {
  int size = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  char mpi_version[MPI_MAX_LIBRARY_VERSION_STRING];
  int len = 0;
  MPI_Get_library_version(mpi_version, &len);
  std::string mpi(mpi_version, static_cast<std::size_t>(len));
  if (auto p = mpi.find('\n'); p != std::string::npos) mpi.resize(p);
  if (auto p = mpi.find(','); p != std::string::npos) mpi.resize(p);
  unsigned h5maj = 0, h5min = 0, h5rel = 0;
  H5get_libversion(&h5maj, &h5min, &h5rel);
  log::info("gen4d {}", build::version);
  log::info("  git revision   {}", build::git_revision);
  log::info("  build          {} ({}), GEN4D_CUDA={}, GEN4D_TORCH={}", build::build_type,
            build::compiler, build::cuda ? "ON" : "OFF", build::torch ? "ON" : "OFF");
  log::info("  MPI            {}; {} rank(s) in this run", mpi, size);
  log::info("  PETSc          {}.{}.{}", PETSC_VERSION_MAJOR, PETSC_VERSION_MINOR,
            PETSC_VERSION_SUBMINOR);
  log::info("  HDF5           {}.{}.{} (parallel)", h5maj, h5min, h5rel);
  log::info("  OpenVDB        {}", OPENVDB_LIBRARY_VERSION_STRING);
  log::info("  GPUs           {}", gpus_seen());
  return 0;
}

std::vector<int> parse_frame_list(const std::string& s) {
  std::vector<int> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      std::size_t used = 0;
      out.push_back(std::stoi(item, &used));
      if (used != item.size()) throw std::invalid_argument(item);
    } catch (const std::exception&) {
      throw InputError("--frames: '" + item + "' is not a frame number (use e.g. 0,10,-1)");
    }
  }
  return out;
}

}  // namespace

int dispatch(int argc, char** argv) {
  CLI::App app{"gen4d: physically based 4D content (ElastoGen voxel elastodynamics) on clusters"};
  app.require_subcommand(1);
  app.set_version_flag("--version", build::version);

  RunArgs ra;
  auto* run = app.add_subcommand("run", "Run a deck (the embedded default scene if no DECK)");
  run->add_option("deck", ra.deck, "TOML deck (see inputs/README.md)")->check(CLI::ExistingFile);
  run->add_option("--out,-o", ra.out, "Output directory (default: output.dir of the deck)");
  run->add_option("--set,-s", ra.sets, "Override a deck key, e.g. --set material.density=500")
      ->take_all();
  run->add_flag("--overwrite", ra.overwrite, "Replace results already in the output directory");

  std::string ckpt, rs_out;
  std::vector<std::string> rs_sets;
  auto* restart =
      app.add_subcommand("restart", "Continue a run from an HDF5 checkpoint (any rank count)");
  restart->add_option("checkpoint", ckpt, "checkpoint_NNNNNN.h5")
      ->required()
      ->check(CLI::ExistingFile);
  restart->add_option("--out,-o", rs_out, "Output directory (default: the checkpoint's)");
  restart->add_option("--set,-s", rs_sets,
                      "Override a key of the stored deck (e.g. simulation.end_time)");

  auto* info =
      app.add_subcommand("info", "Version, git revision, build options, dependencies, ranks, GPUs");

  std::string pv_file, pv_out = "preview", pv_frames = "0,-1";
  int pv_w = 960, pv_h = 720;
  auto* preview = app.add_subcommand("preview", "Render frames of a frames.h5 to PNG images");
  preview->add_option("frames_file", pv_file, "frames.h5 written by gen4d run")
      ->required()
      ->check(CLI::ExistingFile);
  preview->add_option("--out,-o", pv_out, "Directory for the PNG files");
  preview->add_option("--frames", pv_frames,
                      "Comma-separated frame numbers; negative counts from the end");
  preview->add_option("--width", pv_w, "Image width in pixels")->check(CLI::Range(16, 8192));
  preview->add_option("--height", pv_h, "Image height in pixels")->check(CLI::Range(16, 8192));

  app.parse(argc, argv);
  if (*run) return cmd_run(ra);
  if (*restart) return cmd_restart(ckpt, rs_out, rs_sets);
  if (*info) return cmd_info();
  if (*preview) {
    const auto frames = parse_frame_list(pv_frames);
    if (rank_of(MPI_COMM_WORLD) == 0) {
      const io::FrameReader reader(pv_file);
      const int n = static_cast<int>(reader.frames().size());
      std::vector<int> chosen;
      for (int f : frames) {
        const int idx = f < 0 ? n + f : f;
        if (idx < 0 || idx >= n)
          throw InputError(pv_file + ": --frames " + std::to_string(f) +
                           " is out of range; the file holds " + std::to_string(n) + " frame(s)");
        chosen.push_back(idx);
      }
      std::error_code ec;
      fs::create_directories(pv_out, ec);
      if (ec) throw RuntimeError("--out " + pv_out + ": cannot create directory: " + ec.message());
      const auto written = io::render_frames(reader, chosen, pv_out, pv_w, pv_h);
      for (const auto& f : written) log::info("wrote {}", f);
    }
    return 0;
  }
  return 2;
}

}  // namespace gen4d::cli
