#include "cli/Commands.hpp"

#include <CLI/CLI.hpp>
#include <H5public.h>
#include <mpi.h>
#include <openvdb/version.h>
#include <petscversion.h>

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "DefaultDeck.hpp"
#include "cli/NeuralCommands.hpp"
#include "cli/PhysGaussianCommand.hpp"
#include "cli/RenderCommand.hpp"
#include "core/BuildInfo.hpp"
#include "core/Deck.hpp"
#include "core/DeckUse.hpp"
#include "core/Error.hpp"
#include "core/Log.hpp"
#include "core/MemoryEstimate.hpp"
#include "parallel/Signals.hpp"
#include "parallel/Watchdog.hpp"
#include "diagnose/Diagnose.hpp"
#include "diagnose/Effects.hpp"
#include "diagnose/Recording.hpp"
#include "elastogen/Simulation.hpp"
#include "io/Checkpoint.hpp"
#include "io/FrameReader.hpp"
#include "io/PngPreview.hpp"
#include "io/SurfaceIO.hpp"
#include "mpm/MpmSimulation.hpp"
#include "parallel/Collective.hpp"

namespace gen4d::cli {
namespace fs = std::filesystem;

namespace {

struct RunArgs {
  std::string deck;
  std::string out;
  std::vector<std::string> sets;
  bool overwrite = false;
  std::string physgaussian;  //!< a PhysGaussian JSON config instead of a deck
  std::string model_path;    //!< its trained model folder
  bool output_ply = false;   //!< also PhysGaussian's simulation_ply/sim_NNNNNNNNNN.ply files
};

//! Options of run and restart that guard against faults.
struct FaultOptions {
  double watchdog = watchdog::kDefaultSeconds;  //!< --watchdog: seconds without progress
  bool skip_memory_check = false;               //!< --skip-memory-check
};
FaultOptions g_faults;

//! Refuses up front a deck whose estimated memory the machine does not have.
void check_memory(const Config& cfg) {
  if (!g_faults.skip_memory_check) memory::check(MPI_COMM_WORLD, cfg);
}

int rank_of(MPI_Comm c) {
  int r = 0;
  MPI_Comm_rank(c, &r);
  return r;
}

//! Files of a run that gen4d writes, as (folder under OUT, name prefix, suffix) with only
//! digits between prefix and suffix; a suffix without a prefix is one exact name.
struct RunFile {
  const char* dir;
  const char* prefix;
  const char* suffix;
};
constexpr RunFile kRunFiles[] = {
    {"", "checkpoint_", ".h5"},
    {"", ".checkpoint_", ".h5.tmp"},
    {"", "", "frames.h5"},
    {"", "", "frames.xdmf"},
    {"", "", "particles.h5"},
    {"", "", "particles.xdmf"},
    {"surface", "surface_", ".ply"},
    {"surface", "surface_", ".obj"},
    {"particles", "particles_", ".ply"},
    {"volumes", "volume_", ".vdb"},
    {"splats", "splats_", ".ply"},
    {"png", "frame_", ".png"},
};

bool is_run_file(const std::string& name, const RunFile& f) {
  const std::string prefix = f.prefix, suffix = f.suffix;
  if (prefix.empty()) return name == suffix;
  if (name.size() <= prefix.size() + suffix.size() || name.rfind(prefix, 0) != 0 ||
      name.compare(name.size() - suffix.size(), suffix.size(), suffix) != 0)
    return false;
  return std::all_of(name.begin() + static_cast<long>(prefix.size()),
                     name.end() - static_cast<long>(suffix.size()),
                     [](unsigned char c) { return std::isdigit(c) != 0; });
}

//! Removes an earlier run's checkpoints and frames from `out` (kRunFiles only; nothing else).
//! Returns how many files it removed.
long clear_run_files(const std::string& out) {
  long removed = 0;
  for (const RunFile& f : kRunFiles) {
    const fs::path dir = fs::path(out) / f.dir;
    std::error_code ec;
    std::vector<fs::path> doomed;
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec))
      if (it->is_regular_file() && is_run_file(it->path().filename().string(), f))
        doomed.push_back(it->path());
    for (const fs::path& p : doomed) {
      if (!fs::remove(p, ec) && ec)
        throw RuntimeError(p.string() + ": cannot remove the earlier run's file: " + ec.message());
      ++removed;
    }
  }
  return removed;
}

//! Refuses to clobber an earlier run's results unless asked to; with --overwrite, removes the
//! earlier run's checkpoints and frames first (a later run's checkpoint_keep and restarts
//! must not meet them). Decided on rank 0 so every rank takes the same branch.
void check_output_dir(const std::string& out, bool overwrite, const char* frames = "frames.h5") {
  int exists = 0;
  if (rank_of(MPI_COMM_WORLD) == 0) exists = fs::exists(fs::path(out) / frames) ? 1 : 0;
  MPI_Bcast(&exists, 1, MPI_INT, 0, MPI_COMM_WORLD);
  if (exists && !overwrite)
    throw InputError("--out " + out + ": already holds results (" + frames +
                     "); pass --overwrite to replace them or choose another directory");
  if (!overwrite) return;
  parallel::on_rank0(MPI_COMM_WORLD, "rank 0 could not clear the output directory", [&] {
    const long removed = clear_run_files(out);
    if (removed > 0)
      log::info("--overwrite: removed {} file(s) of the earlier run in {}", removed, out);
  });
}

int run_mpm(mpm::MpmSimulation& sim, const std::string& out, bool append) {
  signals::install();
  const auto res = [&] {
    watchdog::Scope watch(g_faults.watchdog);
    return sim.run(out, append);
  }();
  if (res.exit_code == 0)
    log::info("done: {} substeps in {:.2f} s; particles {}/particles.h5 (+ .xdmf), checkpoint {}",
              res.substeps, res.wall_seconds, out, res.last_checkpoint);
  return res.exit_code;
}

//! True when `path` is an MPM particle checkpoint (its format attribute says so); decided on
//! rank 0. Other files go to the voxel checkpoint reader, which reports what is wrong.
bool is_mpm_checkpoint(const std::string& path) {
  int mpm_file = 0;
  if (rank_of(MPI_COMM_WORLD) == 0) {
    io::h5::silence_errors();
    const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    if (f >= 0) {
      io::h5::Handle file(f, H5Fclose);
      if (io::h5::has_attr(file.get(), "format") && io::h5::attr_is_string(file.get(), "format"))
        mpm_file =
            io::h5::read_string_attr(file.get(), "format", path) == mpm::kParticleCheckpointFormat;
    }
  }
  MPI_Bcast(&mpm_file, 1, MPI_INT, 0, MPI_COMM_WORLD);
  return mpm_file != 0;
}

int run_simulation(elastogen::Simulation& sim, const std::string& out, bool append) {
  signals::install();
  const auto res = [&] {
    watchdog::Scope watch(g_faults.watchdog);
    return sim.run(out, append);
  }();
  if (res.exit_code == 0)
    log::info("done: {} steps in {:.2f} s; frames {}/frames.h5 (+ .xdmf), checkpoint {}", res.steps,
              res.wall_seconds, out, res.last_checkpoint);
  return res.exit_code;
}

int cmd_run(const RunArgs& a) {
  if (!a.physgaussian.empty()) {
    // PhysGaussian's scene: converted into OUT/physgaussian/, then run as that deck.
    if (!a.deck.empty()) throw InputError("run: give a DECK or --physgaussian, not both");
    if (a.model_path.empty()) throw InputError("run --physgaussian: --model-path is required");
    const std::string out = a.out.empty() ? "output" : a.out;
    check_output_dir(out, a.overwrite, "particles.h5");
    const std::string deck = convert_physgaussian(MPI_COMM_WORLD, a.physgaussian, a.model_path,
                                                  (fs::path(out) / "physgaussian").string());
    const Config cfg = load_deck(deck, a.sets);
    check_memory(cfg);
    mpm::MpmSimulation sim(MPI_COMM_WORLD, cfg);
    const int code = run_mpm(sim, out, false);
    if (code == 0 && a.output_ply) write_physgaussian_plys(MPI_COMM_WORLD, out);
    return code;
  }
  if (!a.model_path.empty()) throw InputError("run: --model-path needs --physgaussian");
  if (a.output_ply) throw InputError("run: --output-ply needs --physgaussian");
  Config cfg = a.deck.empty()
                   ? parse_deck(default_deck_text, "<embedded default>", default_deck_dir(), a.sets)
                   : load_deck(a.deck, a.sets);
  const std::string out = a.out.empty() ? cfg.output.dir : a.out;
  check_memory(cfg);
  if (cfg.solver.method == "mpm") {
    mpm::MpmSimulation sim(MPI_COMM_WORLD, cfg);  // validates material and geometry
    check_output_dir(out, a.overwrite, "particles.h5");
    return run_mpm(sim, out, false);
  }
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);  // validates geometry; writes nothing
  check_output_dir(out, a.overwrite);
  return run_simulation(sim, out, false);
}

//! Where a restart writes (--out, else the checkpoint's folder) and whether that folder already
//! holds the run's frames file (`frames`), which the restart then continues. Collective.
std::pair<std::string, bool> restart_target(const std::string& checkpoint,
                                            const std::string& out_arg, const char* frames) {
  const std::string out = out_arg.empty() ? fs::path(checkpoint).parent_path().string() : out_arg;
  const std::string dir = out.empty() ? "." : out;
  int exists = 0;
  if (rank_of(MPI_COMM_WORLD) == 0) exists = fs::exists(fs::path(dir) / frames) ? 1 : 0;
  MPI_Bcast(&exists, 1, MPI_INT, 0, MPI_COMM_WORLD);
  return {dir, exists != 0};
}

int cmd_restart(const std::string& checkpoint, const std::string& out_arg,
                const std::vector<std::string>& sets) {
  const std::string stored = checkpoint + " (stored deck)";
  if (is_mpm_checkpoint(checkpoint)) {
    const auto meta = mpm::read_particle_checkpoint_meta(MPI_COMM_WORLD, checkpoint);
    Config cfg = parse_deck(meta.deck_text, stored, ".", sets);
    check_memory(cfg);
    mpm::MpmSimulation sim(MPI_COMM_WORLD, cfg, false);
    sim.load_checkpoint(checkpoint);
    const auto [dir, append] = restart_target(checkpoint, out_arg, "particles.h5");
    return run_mpm(sim, dir, append);
  }
  const io::CheckpointMeta meta = io::read_checkpoint_meta(MPI_COMM_WORLD, checkpoint);
  Config cfg = parse_deck(meta.deck_text, stored, ".", sets);
  check_memory(cfg);
  elastogen::Simulation sim(MPI_COMM_WORLD, cfg);
  sim.load_checkpoint(checkpoint);
  const auto [dir, append] = restart_target(checkpoint, out_arg, "frames.h5");
  return run_simulation(sim, dir, append);
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

//! Frame numbers of --frames; "all" gives every frame (an empty list).
std::vector<int> parse_frame_list(const std::string& s) {
  std::vector<int> out;
  if (s == "all") return out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      std::size_t used = 0;
      out.push_back(std::stoi(item, &used));
      if (used != item.size()) throw std::invalid_argument(item);
    } catch (const std::exception&) {
      throw InputError("--frames: '" + item + "' is not a frame number (use e.g. 0,10,-1 or all)");
    }
  }
  return out;
}

//! Positions in a sequence of n frames (negative counts from the end; empty list = all).
std::vector<int> choose_frames(const std::vector<int>& frames, int n, const std::string& what) {
  std::vector<int> chosen;
  if (frames.empty())
    for (int i = 0; i < n; ++i) chosen.push_back(i);
  for (int f : frames) {
    const int idx = f < 0 ? n + f : f;
    if (idx < 0 || idx >= n)
      throw InputError(what + ": --frames " + std::to_string(f) + " is out of range; it holds " +
                       std::to_string(n) + " frame(s)");
    chosen.push_back(idx);
  }
  return chosen;
}

//! The ffmpeg executable on PATH, or "".
std::string find_ffmpeg() {
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path ? path : "");
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    if (dir.empty()) continue;
    const fs::path candidate = fs::path(dir) / "ffmpeg";
    if (::access(candidate.c_str(), X_OK) == 0) return candidate.string();
  }
  return "";
}

std::string shell_quoted(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

//! Assembles the PNGs into out_dir/preview.mp4 with ffmpeg when it is on PATH; a note otherwise.
void assemble_mp4(const std::vector<std::string>& pngs, const std::string& out_dir, double fps) {
  const std::string ffmpeg = find_ffmpeg();
  if (ffmpeg.empty()) {
    log::info("--mp4: ffmpeg is not on PATH; skipped the video (the PNG files are written)");
    return;
  }
  if (pngs.empty()) return;
  const fs::path list = fs::path(out_dir) / ".preview-frames.txt";
  {
    std::ofstream out(list);
    for (const auto& p : pngs)
      out << "file " << shell_quoted(fs::absolute(p).string()) << "\nduration " << 1.0 / fps
          << "\n";
    if (!out) throw RuntimeError(list.string() + ": cannot write the frame list for ffmpeg");
  }
  const fs::path mp4 = fs::path(out_dir) / "preview.mp4";
  const fs::path temp = fs::path(out_dir) / ".preview.mp4.tmp";
  const std::string cmd =
      shell_quoted(ffmpeg) + " -hide_banner -loglevel error -y -f concat -safe 0 -i " +
      shell_quoted(list.string()) + " -vf 'scale=trunc(iw/2)*2:trunc(ih/2)*2,format=yuv420p' -r " +
      std::to_string(fps) + " -f mp4 " + shell_quoted(temp.string());
  const int rc = std::system(cmd.c_str());
  std::error_code ec;
  fs::remove(list, ec);
  if (rc != 0) {
    fs::remove(temp, ec);
    throw RuntimeError("--mp4: ffmpeg failed (exit status " + std::to_string(rc) + ")");
  }
  fs::rename(temp, mp4, ec);
  if (ec) throw RuntimeError(mp4.string() + ": cannot rename the video: " + ec.message());
  log::info("wrote {}", mp4.string());
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
  run->add_option("--physgaussian", ra.physgaussian,
                  "A PhysGaussian JSON config to run instead of a deck (with --model-path)")
      ->check(CLI::ExistingFile);
  run->add_option("--model-path", ra.model_path,
                  "The trained 3DGS model folder of --physgaussian (point_cloud/iteration_N/)");
  run->add_option("--output-path", ra.out, "Same as --out (PhysGaussian's spelling)");
  run->add_flag("--output-ply", ra.output_ply,
                "With --physgaussian: also OUT/simulation_ply/sim_NNNNNNNNNN.ply per frame "
                "(particle positions, as PhysGaussian's --output_ply)");
  std::string cv_config, cv_model, cv_out;
  auto* convert = app.add_subcommand(
      "convert-physgaussian", "Write the gen4d deck (and simulated PLY) of a PhysGaussian config");
  convert->add_option("config", cv_config, "PhysGaussian JSON config")
      ->required()
      ->check(CLI::ExistingFile);
  convert->add_option("--model-path", cv_model, "Trained 3DGS model folder")->required();
  convert->add_option("--out,-o", cv_out, "Folder for deck.toml and object.ply")->required();
  bool run_mp4 = false, restart_mp4 = false;
  run->add_flag("--mp4", run_mp4,
                "Render every output frame (as [render]) and assemble OUT/render.mp4 (ffmpeg)");

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
  restart->add_flag("--mp4", restart_mp4, "Render every output frame and assemble OUT/render.mp4");
  for (CLI::App* command : {run, restart}) {
    command
        ->add_option("--watchdog", g_faults.watchdog,
                     "Abort the job when a rank makes no progress for this many seconds (a "
                     "rank hung or dead); 0: no watchdog")
        ->capture_default_str()
        ->check(CLI::NonNegativeNumber);
    command->add_flag("--skip-memory-check", g_faults.skip_memory_check,
                      "Run even when the deck's memory estimate exceeds the available memory");
  }

  auto* info =
      app.add_subcommand("info", "Version, git revision, build options, dependencies, ranks, GPUs");

  std::string pv_file, pv_out = "preview", pv_frames = "0,-1", pv_mode = "auto";
  int pv_w = 960, pv_h = 720;
  double pv_fps = 25;
  bool pv_no_ground = false, pv_mp4 = false;
  auto* preview = app.add_subcommand(
      "preview",
      "Render frames of a run (voxel surface from frames.h5, or its surface sequence) "
      "to PNG images");
  preview
      ->add_option("run", pv_file,
                   "frames.h5 (or an MPM run's particles.h5) written by gen4d run, or the "
                   "run's directory")
      ->required()
      ->check(CLI::ExistingPath);
  preview->add_option("--out,-o", pv_out, "Directory for the PNG files");
  auto* pv_frames_opt = preview->add_option(
      "--frames", pv_frames, "Comma-separated frame numbers, negative from the end, or all");
  preview
      ->add_option("--mode", pv_mode,
                   "surface: the run's surface/ sequence (mesh or voxel boundary); voxels: "
                   "the voxel boundary from frames.h5; auto: surface when the run has one")
      ->check(CLI::IsMember({"auto", "surface", "voxels"}));
  preview->add_option("--width", pv_w, "Image width in pixels")->check(CLI::Range(16, 8192));
  preview->add_option("--height", pv_h, "Image height in pixels")->check(CLI::Range(16, 8192));
  preview->add_flag("--no-ground", pv_no_ground, "Surface mode: no ground grid");
  preview->add_flag("--mp4", pv_mp4,
                    "Also assemble the images into preview.mp4 if ffmpeg is on PATH (all frames "
                    "unless --frames is given)");
  preview->add_option("--fps", pv_fps, "Frame rate of the --mp4 video")->check(CLI::Range(1, 240));

  std::string dg_deck, dg_effects;
  std::vector<std::string> dg_sets;
  diagnose::DiagnoseOptions dg;
  auto* diag = app.add_subcommand(
      "diagnose",
      "Find where and when a recording departs from a deck, name the missing physics, fit it");
  diag->add_option("deck", dg_deck, "The nominal deck (TOML)")
      ->required()
      ->check(CLI::ExistingFile);
  diag->add_option("--recording,-r", dg.recordings,
                   "Recording: CSV marker,X,Y,Z,t,x,y,z or sensor,X,Y,Z,t,ax,ay,az, or HDF5; "
                   "repeat for more files")
      ->required()
      ->check(CLI::ExistingFile);
  diag->add_option("--out,-o", dg.out_dir, "Output directory for report.json, report.md, PNGs")
      ->required();
  CLI::Option* dg_effects_opt = diag->add_option("--effects", dg_effects, [] {
    std::string in, out;
    for (const auto& e : diagnose::effect_library()) {
      std::string& list = e->in_default_library() ? in : out;
      list += (list.empty() ? "" : ",") + e->name();
    }
    return "Comma-separated candidate effects, or 'all' (default: " + in +
           "; tried only when named or with 'all': " + out + ")";
  }());
  diag->add_option("--holdout", dg.holdout,
                   "Fraction of time blocks and of markers held out for model selection")
      ->check(CLI::Range(0.0, 0.5));
  diag->add_option("--refit", dg.refit, "Candidates refitted after screening")
      ->check(CLI::Range(1, 10));
  bool dg_no_refinement = false;
  diag->add_flag("--no-refinement-check", dg_no_refinement,
                 "Skip the h/2 rerun that measures the model's discretisation error before an "
                 "effect is kept (it costs about 20 forward runs' time; without it only the 20 % "
                 "held-out rule guards against absorbed discretisation error)");
  std::string dg_unmeasured;
  CLI::Option* dg_unmeasured_opt = diag->add_option(
      "--unmeasured", dg_unmeasured,
      "Comma-separated value columns (x,y,z,ax,ay,az) not measured, for files that write 0 "
      "for an axis the sensor lacks; applies to every --recording. An empty CSV cell, a value "
      "column left out of the header or NaN in HDF5 are not measured anyway");
  diag->add_option("--lowpass", dg.lowpass_hz,
                   "The recording was low-pass filtered at this cutoff (Hz) forwards and "
                   "backwards: every prediction is filtered alike (4th-order Butterworth, zero "
                   "phase)")
      ->check(CLI::PositiveNumber);
  diag->add_flag("--hold-poisson", dg.hold_poisson,
                 "Calibrate E alone, nu held at the deck's value (a known nu, or a recording "
                 "that cannot see it: one axis of one sensor, where a fitted nu only trades "
                 "with E)");
  diag->add_option("--set,-s", dg_sets, "Override a deck key, e.g. --set simulation.dt=0.001")
      ->take_all();

  const NeuralCommands neural(app);
  const RenderCommand render(app);

  try {
    app.parse(argc, argv);
  } catch (const CLI::Success& e) {  // --help, --help-all, --version: print them (rank 0)
    return rank_of(MPI_COMM_WORLD) == 0 ? app.exit(e) : 0;
  }
  if (const int code = neural.run(); code >= 0) return code;
  if (const int code = render.run(); code >= 0) return code;
  // --mp4 is the deck key render.video = "mp4" (a [render] table is added where there is none).
  if (run_mp4) ra.sets.push_back("render.video=\"mp4\"");
  if (restart_mp4) rs_sets.push_back("render.video=\"mp4\"");
  if (*convert) {
    convert_physgaussian(MPI_COMM_WORLD, cv_config, cv_model, cv_out);
    return 0;
  }
  if (*run) return cmd_run(ra);
  if (*restart) return cmd_restart(ckpt, rs_out, rs_sets);
  if (*info) return cmd_info();
  if (*diag) {
    const Config cfg = load_deck(dg_deck, dg_sets);
    check_deck_use(cfg, DeckUser::Diagnose);
    std::stringstream ss(dg_effects);
    for (std::string e; std::getline(ss, e, ',');)
      if (!e.empty() && std::find(dg.effects.begin(), dg.effects.end(), e) == dg.effects.end())
        dg.effects.push_back(e);  // each once: a repeated name would be refitted twice
    // An explicit list that names nothing is a mistake, not a request for the whole library.
    if (dg_effects_opt->count() > 0 && dg.effects.empty())
      throw InputError("command line: --effects '" + dg_effects +
                       "' names no effect (a comma-separated list of library effects)");
    if (dg.effects.size() > 1 &&
        std::find(dg.effects.begin(), dg.effects.end(), "all") != dg.effects.end())
      throw InputError("command line: --effects '" + dg_effects +
                       "': 'all' names every effect, so it stands alone");
    dg.refinement_check = !dg_no_refinement;
    std::stringstream us(dg_unmeasured);
    const auto& columns = diagnose::value_column_names();
    for (std::string u; std::getline(us, u, ',');) {
      if (u.empty()) continue;
      if (std::find(columns.begin(), columns.end(), u) == columns.end())
        throw InputError("command line: --unmeasured '" + dg_unmeasured + "': '" + u +
                         "' is not a value column (x, y, z, ax, ay, az)");
      dg.unmeasured.push_back(u);
    }
    if (dg_unmeasured_opt->count() > 0 && dg.unmeasured.empty())
      throw InputError("command line: --unmeasured '" + dg_unmeasured +
                       "' names no column (a comma-separated list of x, y, z, ax, ay, az)");
    return diagnose::run_diagnose(MPI_COMM_WORLD, cfg, dg);
  }
  if (*preview) {
    const bool all = pv_mp4 && pv_frames_opt->count() == 0;
    const auto frames = parse_frame_list(all ? "all" : pv_frames);
    if (rank_of(MPI_COMM_WORLD) == 0) {
      const bool is_dir = fs::is_directory(pv_file);
      const fs::path run_dir = is_dir ? fs::path(pv_file) : fs::path(pv_file).parent_path();
      const fs::path particles = is_dir ? run_dir / "particles.h5" : fs::path(pv_file);
      if (fs::exists(particles) && particles.filename() == "particles.h5" &&
          !fs::exists(run_dir / "frames.h5")) {
        // An MPM run: depth-shaded particle splats seen along -y.
        std::error_code ec;
        fs::create_directories(pv_out, ec);
        if (ec)
          throw RuntimeError("--out " + pv_out + ": cannot create directory: " + ec.message());
        const auto list = mpm::read_particle_frame_list(particles.string());
        const auto chosen =
            choose_frames(frames, static_cast<int>(list.size()), particles.string());
        const auto written =
            mpm::render_particle_frames(particles.string(), chosen, pv_out, pv_w, pv_h);
        for (const auto& f : written) log::info("wrote {}", f);
        if (pv_mp4) assemble_mp4(written, pv_out, pv_fps);
        return 0;
      }
      const std::string frames_file = is_dir ? (run_dir / "frames.h5").string() : pv_file;
      const std::string surface_dir = (run_dir / io::kSurfaceDir).string();
      const auto sequence = io::list_surface_sequence(surface_dir);
      const bool surface = pv_mode == "surface" || (pv_mode == "auto" && !sequence.empty());
      if (surface && sequence.empty())
        throw InputError(surface_dir +
                         ": no surface_NNNNNN.ply or .obj files; run with output.surface = "
                         "\"ply\" or \"obj\"");
      std::error_code ec;
      fs::create_directories(pv_out, ec);
      if (ec) throw RuntimeError("--out " + pv_out + ": cannot create directory: " + ec.message());
      std::vector<std::string> written;
      if (surface) {
        const auto chosen = choose_frames(frames, static_cast<int>(sequence.size()), surface_dir);
        written = io::render_surface_frames(sequence, chosen, pv_out, pv_w, pv_h, !pv_no_ground);
      } else {
        const io::FrameReader reader(frames_file);
        const auto chosen = choose_frames(frames, reader.frame_count(), frames_file);
        written = io::render_frames(reader, chosen, pv_out, pv_w, pv_h);
      }
      for (const auto& f : written) log::info("wrote {}", f);
      if (pv_mp4) assemble_mp4(written, pv_out, pv_fps);
    }
    return 0;
  }
  return 2;
}

}  // namespace gen4d::cli
