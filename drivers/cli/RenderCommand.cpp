// gen4d render: draws a trained 3DGS object with the CPU rasterizer (gaussians/Render.hpp).
//
// Sample runs:
//   gen4d render point_cloud.ply --camera cameras.json:3 --out view3.png
//   mpirun -np 2 gen4d render point_cloud.ply --out orbit.png --azimuth 120 --elevation 30
//
// Every rank reads the PLY and draws its share of the splats (render_distributed: the image is
// the same for any rank count); rank 0 writes the PNG. Inputs are checked before anything is
// written, so a bad call leaves no file behind.
#include "cli/RenderCommand.hpp"

#include <CLI/CLI.hpp>
#include <mpi.h>

#include <array>
#include <chrono>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "core/Error.hpp"
#include "core/Log.hpp"
#include "gaussians/Camera.hpp"
#include "gaussians/Kinematics.hpp"
#include "gaussians/Ply.hpp"
#include "gaussians/Render.hpp"
#include "SplatBlock.hpp"

namespace gen4d::cli {

struct RenderCommand::State {
  CLI::App* cmd = nullptr;
  std::string splats, camera, out, bg = "0,0,0", center, up = "0,0,1";
  CLI::Option *center_opt = nullptr, *radius_opt = nullptr, *camera_opt = nullptr;
  double azimuth = 45, elevation = 20, radius = 0, fov = 45;
  int width = 960, height = 720, threads = 0;
};

RenderCommand::RenderCommand(CLI::App& app) : s_(std::make_unique<State>()) {
  State& s = *s_;
  s.cmd = app.add_subcommand(
      "render", "Render a 3DGS point cloud (PLY) to a PNG with the 3DGS rasterizer's rules");
  s.cmd->add_option("splats", s.splats, "3DGS point_cloud.ply")->required();
  s.camera_opt = s.cmd->add_option(
      "--camera", s.camera,
      "3DGS cameras.json[:INDEX] (default index 0); without it an orbit camera (below), "
      "framing the splats unless --orbit-center / --radius are given");
  s.cmd->add_option("--out,-o", s.out, "Output PNG")->required();
  s.cmd->add_option("--bg", s.bg, "Background colour R,G,B in [0, 1]");
  s.center_opt = s.cmd->add_option("--orbit-center", s.center, "Orbit centre x,y,z");
  s.cmd->add_option("--up", s.up, "Orbit up axis x,y,z");
  s.cmd->add_option("--azimuth", s.azimuth, "Orbit azimuth about the up axis, degrees");
  s.cmd->add_option("--elevation", s.elevation, "Orbit elevation, degrees")
      ->check(CLI::Range(-90.0, 90.0));
  s.radius_opt = s.cmd->add_option("--radius", s.radius, "Orbit radius (world units)")
                     ->check(CLI::PositiveNumber);
  s.cmd->add_option("--width", s.width, "Orbit image width")->check(CLI::Range(1, 16384));
  s.cmd->add_option("--height", s.height, "Orbit image height")->check(CLI::Range(1, 16384));
  s.cmd->add_option("--fov", s.fov, "Orbit vertical field of view, degrees")
      ->check(CLI::Range(1.0, 179.0));
  s.cmd->add_option("--threads", s.threads, "Threads per rank (0: the cores shared by the ranks)")
      ->check(CLI::Range(0, 1024));
  for (const char* o : {"--orbit-center", "--up", "--azimuth", "--elevation", "--radius", "--width",
                        "--height", "--fov"})
    s.camera_opt->excludes(o);
}

RenderCommand::~RenderCommand() = default;

namespace {

//! "a,b,c" as three finite numbers; InputError naming the option otherwise.
std::array<double, 3> triple(const std::string& text, const char* option) {
  std::array<double, 3> v{};
  std::stringstream ss(text);
  std::string item;
  int n = 0;
  while (std::getline(ss, item, ',')) {
    std::size_t used = 0;
    double x = 0;
    try {
      x = std::stod(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (n >= 3 || used == 0 || item.find_first_not_of(" \t", used) != std::string::npos ||
        !std::isfinite(x))
      n = 4;
    else
      v[static_cast<std::size_t>(n++)] = x;
  }
  if (n != 3)
    throw InputError(std::string("command line: ") + option + " '" + text +
                     "' must be three comma-separated numbers");
  return v;
}

}  // namespace

int RenderCommand::run() const {
  const State& s = *s_;
  if (!*s.cmd) return -1;
  int rank = 0, ranks = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &ranks);
  // The command line first, then the files: nothing is written before all of them are read.
  const auto bg = triple(s.bg, "--bg");
  for (double c : bg)
    if (c < 0 || c > 1)
      throw InputError("command line: --bg '" + s.bg + "' must hold colour channels in [0, 1]");
  const auto up = triple(s.up, "--up");
  if (up[0] == 0 && up[1] == 0 && up[2] == 0)
    throw InputError("command line: --up must not be the zero vector");
  const auto t0 = std::chrono::steady_clock::now();
  const gaussians::SplatSet set = gaussians::read_splats_ply(s.splats);
  if (set.size() == 0) throw InputError(s.splats + ": the point cloud holds no splats");
  gaussians::Camera camera;
  if (!s.camera.empty()) {
    camera = gaussians::read_camera_spec(s.camera);
  } else {
    const gaussians::SplatFrame all = gaussians::rest_frame(set);
    gaussians::OrbitCamera orbit = gaussians::framing_orbit(all, s.width, s.height, s.fov, up);
    if (s.center_opt->count() > 0) orbit.center = triple(s.center, "--orbit-center");
    if (s.radius_opt->count() > 0) orbit.radius = s.radius;
    orbit.azimuth = s.azimuth;
    orbit.elevation = s.elevation;
    camera = orbit.at_frame(0);
  }

  const gaussians::SplatFrame frame =
      gaussians::rest_frame(driver::rank_share(MPI_COMM_WORLD, set));

  gaussians::RenderOptions opt;
  opt.background = {static_cast<float>(bg[0]), static_cast<float>(bg[1]),
                    static_cast<float>(bg[2])};
  opt.threads = s.threads;
  const gaussians::Image img = gaussians::render_distributed(MPI_COMM_WORLD, frame, camera, opt);
  if (rank == 0) {
    gaussians::write_image_png(s.out, img);
    const double secs =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    log::info("wrote {} ({}x{}, {} splats, SH degree {}, {} rank(s), {:.2f} s)", s.out, img.width,
              img.height, set.size(), set.sh_degree, ranks, secs);
  }
  return 0;
}

}  // namespace gen4d::cli
