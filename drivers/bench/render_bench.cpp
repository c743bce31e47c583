// 3DGS rasterizer throughput on this machine, printed as JSON, at the rank count it runs with:
//   1. the donut (a trained object, SH degree 0) at 1280x720 from a framing orbit camera;
//   2. --splats synthetic splats (SH degree 3, random anisotropic covariances) at 1920x1080;
// each as frames/s of render_distributed (image split by tile rows, the splats spread over the
// ranks in blocks), with phase times (max over ranks: preprocess, exchange, sort, blend,
// gather). Baselines timed in the same run: the per-pixel brute-force reference on a small
// image of the donut (same image bit for bit), and, as the lower bound of the other split
// (each rank composites its own splats over the whole image), the slowest rank's plain render
// of its share of the splats.
// Strong scaling: run with mpirun -np 1 and -np 2.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <thread>

#include "SyntheticSplats.hpp"
#include "gaussians/Kinematics.hpp"
#include "gaussians/Ply.hpp"
#include "gaussians/Render.hpp"
#include "validation/DriverCommon.hpp"

namespace gen4d {
namespace {

using gaussians::Camera;
using gaussians::Image;
using gaussians::RenderOptions;
using gaussians::RenderStats;
using gaussians::SplatFrame;

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

double max_over(MPI_Comm comm, double v) {
  double m = v;
  MPI_Allreduce(&v, &m, 1, MPI_DOUBLE, MPI_MAX, comm);
  return m;
}

//! Splats [lo, hi) of `all`.
SplatFrame block(const SplatFrame& all, std::size_t lo, std::size_t hi) {
  SplatFrame s;
  s.sh_degree = all.sh_degree;
  const std::size_t k = 3 * static_cast<std::size_t>(all.coefficients());
  s.position.assign(all.position.begin() + 3 * lo, all.position.begin() + 3 * hi);
  s.covariance.assign(all.covariance.begin() + 6 * lo, all.covariance.begin() + 6 * hi);
  s.opacity.assign(all.opacity.begin() + lo, all.opacity.begin() + hi);
  s.sh.assign(all.sh.begin() + k * lo, all.sh.begin() + k * hi);
  return s;
}

//! This rank's block of `n` synthetic SH-3 splats in a unit ball (splat i drawn from a generator
//! seeded by i, so the union does not depend on the rank count).
SplatFrame synthetic(long n, int rank, int ranks) {
  const std::size_t lo = static_cast<std::size_t>(n) * rank / ranks;
  const std::size_t hi = static_cast<std::size_t>(n) * (rank + 1) / ranks;
  SplatFrame s;
  s.sh_degree = 3;
  const double scale = 0.6 / std::cbrt(static_cast<double>(n));  // about touching neighbours
  for (std::size_t i = lo; i < hi; ++i) {
    std::mt19937 rng(static_cast<unsigned>(i * 2654435761u + 1));
    std::uniform_real_distribution<double> u(-1, 1), o(0.05, 0.99), c(-1, 1);
    double p[3];
    do {
      for (double& x : p) x = u(rng);
    } while (p[0] * p[0] + p[1] * p[1] + p[2] * p[2] > 1);
    for (double x : p) s.position.push_back(static_cast<float>(x));
    for (double v : synthetic::random_covariance(rng, 0.3 * scale, scale))
      s.covariance.push_back(static_cast<float>(v));
    s.opacity.push_back(static_cast<float>(o(rng)));
    for (int j = 0; j < 48; ++j) s.sh.push_back(static_cast<float>(c(rng) * (j < 3 ? 1.0 : 0.3)));
  }
  return s;
}

struct Timing {
  double fps = 0, frame_s = 0, local_only_s = 0;
  RenderStats stats;  //!< per frame, max over ranks
  std::size_t visible = 0;
};

//! `frames` timed distributed renders after a warm-up, and the other split's lower bound.
Timing time_case(MPI_Comm comm, const SplatFrame& local, const Camera& cam, int frames,
                 int threads) {
  RenderOptions opt;
  opt.threads = threads;
  render_distributed(comm, local, cam, opt);  // warm-up
  RenderStats st;
  opt.stats = &st;
  MPI_Barrier(comm);
  const double t0 = now();
  for (int f = 0; f < frames; ++f) render_distributed(comm, local, cam, opt);
  const double elapsed = max_over(comm, now() - t0);
  Timing t;
  t.frame_s = elapsed / frames;
  t.fps = frames / elapsed;
  t.stats.preprocess = max_over(comm, st.preprocess / frames);
  t.stats.exchange = max_over(comm, st.exchange / frames);
  t.stats.sort = max_over(comm, st.sort / frames);
  t.stats.blend = max_over(comm, st.blend / frames);
  t.stats.gather = max_over(comm, st.gather / frames);
  unsigned long long vis = st.visible / static_cast<std::size_t>(frames), all = 0;
  MPI_Allreduce(&vis, &all, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, comm);
  t.visible = all;
  // Split (b)'s floor: each rank composites its own splats over the whole image.
  RenderOptions lopt;
  int node_ranks = 1;
  MPI_Comm node;
  MPI_Comm_split_type(comm, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node);
  MPI_Comm_size(node, &node_ranks);
  MPI_Comm_free(&node);
  lopt.threads =
      threads > 0 ? threads
                  : std::max(1, static_cast<int>(std::thread::hardware_concurrency()) / node_ranks);
  MPI_Barrier(comm);
  const double t1 = now();
  for (int f = 0; f < frames; ++f) gaussians::render(local, cam, lopt);
  t.local_only_s = max_over(comm, now() - t1) / frames;
  return t;
}

std::string json_case(const char* name, long splats, const Camera& cam, int sh, const Timing& t) {
  char buf[1024];
  std::snprintf(buf, sizeof buf,
                "    {\"case\": \"%s\", \"splats\": %ld, \"sh_degree\": %d, \"width\": %d, "
                "\"height\": %d, \"visible\": %zu,\n     \"frames_per_s\": %.3f, "
                "\"frame_s\": %.4f, \"phases_s\": {\"preprocess\": %.4f, \"exchange\": %.4f, "
                "\"sort\": %.4f, \"blend\": %.4f, \"gather\": %.4f},\n"
                "     \"split_b_lower_bound_s\": %.4f}",
                name, splats, sh, cam.width, cam.height, t.visible, t.fps, t.frame_s,
                t.stats.preprocess, t.stats.exchange, t.stats.sort, t.stats.blend, t.stats.gather,
                t.local_only_s);
  return buf;
}

int run(const std::string& donut_path, long splats, int frames, int threads) {
  MPI_Comm comm = MPI_COMM_WORLD;
  int rank = 0, ranks = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &ranks);
  std::string cases;
  std::string baseline = "null";
  if (!donut_path.empty() && std::filesystem::exists(donut_path)) {
    const SplatFrame all = gaussians::rest_frame(gaussians::read_splats_ply(donut_path));
    const std::size_t n = all.size();
    const SplatFrame local = block(all, n * rank / ranks, n * (rank + 1) / ranks);
    const Camera cam = gaussians::framing_orbit(all, 1280, 720, 40).at_frame(0);
    const Timing t = time_case(comm, local, cam, frames, threads);
    cases += json_case("donut", static_cast<long>(n), cam, all.sh_degree, t);
    // Brute-force reference vs the tiled renderer on a small image, one thread, rank 0.
    if (rank == 0) {
      const Camera small = gaussians::framing_orbit(all, 96, 54, 40).at_frame(0);
      RenderOptions one;
      one.threads = 1;
      double t0 = now();
      const Image brute = gaussians::render_brute_force(all, small, one);
      const double brute_s = now() - t0;
      t0 = now();
      const int reps = 20;
      Image tiled;
      for (int r = 0; r < reps; ++r) tiled = gaussians::render(all, small, one);
      const double tiled_s = (now() - t0) / reps;
      char buf[256];
      std::snprintf(buf, sizeof buf,
                    "{\"image\": \"96x54 donut, 1 thread\", \"brute_force_s\": %.4f, "
                    "\"tiled_s\": %.5f, \"speedup\": %.1f, \"identical\": %s}",
                    brute_s, tiled_s, brute_s / tiled_s, brute.rgb == tiled.rgb ? "true" : "false");
      baseline = buf;
    }
  } else if (rank == 0) {
    log::warn("bench_render: {} not found; the donut case is skipped (--donut)", donut_path);
  }
  if (splats > 0) {
    const SplatFrame local = synthetic(splats, rank, ranks);
    gaussians::OrbitCamera orbit;
    orbit.width = 1920;
    orbit.height = 1080;
    orbit.radius = 2.6;
    orbit.fov_y_degrees = 45;
    orbit.azimuth = 30;
    const Camera cam = orbit.at_frame(0);
    const Timing t = time_case(comm, local, cam, std::max(1, frames / 2), threads);
    if (!cases.empty()) cases += ",\n";
    cases += json_case("synthetic", splats, cam, 3, t);
  }
  if (rank == 0)
    std::printf(
        "{\n  \"benchmark\": \"render\",\n  \"ranks\": %d,\n  \"threads_per_rank\": %d,\n"
        "  \"baseline\": %s,\n  \"cases\": [\n%s\n  ]\n}\n",
        ranks,
        threads > 0 ? threads
                    : std::max(1, static_cast<int>(std::thread::hardware_concurrency()) / ranks),
        baseline.c_str(), cases.c_str());
  return 0;
}

}  // namespace
}  // namespace gen4d

int main(int argc, char** argv) {
  std::string donut = "../shared/data/splats/donut/point_cloud.ply";
  long splats = 1000000;
  int frames = 6, threads = 0;
  return gen4d::driver::main_with(
      argc, argv, "3DGS rasterizer frames/s (donut at 720p, synthetic SH-3 at 1080p), as JSON",
      [&](CLI::App& app) {
        app.add_option("--donut", donut, "The donut's point_cloud.ply (skipped when missing)");
        app.add_option("--splats", splats, "Synthetic splats (0: skip that case)")
            ->check(CLI::Range(0L, 100000000L));
        app.add_option("--frames", frames, "Timed frames of the donut (half for synthetic)")
            ->check(CLI::Range(1, 10000));
        app.add_option("--threads", threads, "Threads per rank (0: cores / ranks on the node)")
            ->check(CLI::Range(0, 1024));
      },
      [&] { return gen4d::run(donut, splats, frames, threads); });
}
