// 3DGS rasterizer throughput on this machine, printed as JSON, at the rank count it runs with:
//   1. the donut (a trained object, SH degree 0) at 1280x720 from a framing orbit camera;
//   2. --splats synthetic splats (SH degree 3, random anisotropic covariances) at 1920x1080;
// each as frames/s of render_distributed (image split by tile rows, the splats spread over the
// ranks in blocks) on the host threads (OMP_NUM_THREADS, else the node's cores per rank), with
// phase times (max over ranks: preprocess, exchange, sort, blend, gather). Baselines timed in
// the same run: the previous sort and blend (RenderOptions::legacy, "identical": the same image
// bit for bit), the per-pixel brute-force reference on a small image of the donut, and, as the
// lower bound of the other split (each rank composites its own splats over the whole image),
// the slowest rank's plain render of its share of the splats. Where the rank has a GPU, the
// synthetic case is also rendered there ("gpu": frames/s with the upload of the splats, and
// with the splats already on the device); "gpu": "skipped: <why>" otherwise.
// Strong scaling: run with mpirun -np 1 and -np 2.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <utility>

#include "SyntheticSplats.hpp"
#include "gaussians/Kinematics.hpp"
#include "gaussians/Ply.hpp"
#include "core/Device.hpp"
#include "core/ParallelFor.hpp"
#include "gaussians/Render.hpp"
#include "gaussians/RenderDetail.hpp"
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
  double fps = 0, frame_s = 0, legacy_fps = 0, local_only_s = 0;
  bool identical = false;  //!< the legacy path's image equals the new one bit for bit
  Image image;             //!< the last image (rank 0)
  RenderStats stats;       //!< per frame, max over ranks
  std::size_t visible = 0;
};

//! Phase times per frame, max over ranks.
RenderStats per_frame(MPI_Comm comm, const RenderStats& st, int frames) {
  RenderStats t;
  t.preprocess = max_over(comm, st.preprocess / frames);
  t.exchange = max_over(comm, st.exchange / frames);
  t.sort = max_over(comm, st.sort / frames);
  t.blend = max_over(comm, st.blend / frames);
  t.gather = max_over(comm, st.gather / frames);
  t.transfer = max_over(comm, st.transfer / frames);
  return t;
}

//! Seconds per frame of `frames` render_distributed calls with `opt` (after a warm-up), the
//! last image in `last` (rank 0).
double time_renders(MPI_Comm comm, const SplatFrame& local, const Camera& cam, int frames,
                    RenderOptions opt, Image& last) {
  RenderStats* stats = opt.stats;
  opt.stats = nullptr;
  last = render_distributed(comm, local, cam, opt);  // warm-up
  opt.stats = stats;
  MPI_Barrier(comm);
  const double t0 = now();
  for (int f = 0; f < frames; ++f) last = render_distributed(comm, local, cam, opt);
  return max_over(comm, now() - t0) / frames;
}

//! `frames` timed distributed renders (new and legacy) after a warm-up, and the other split's
//! lower bound.
Timing time_case(MPI_Comm comm, const SplatFrame& local, const Camera& cam, int frames,
                 int threads) {
  RenderOptions opt;
  opt.threads = threads;
  opt.device = false;
  RenderStats st;
  opt.stats = &st;
  Image fresh, legacy;
  Timing t;
  t.frame_s = time_renders(comm, local, cam, frames, opt, fresh);
  t.fps = 1 / t.frame_s;
  t.stats = per_frame(comm, st, frames);
  unsigned long long vis = st.visible / static_cast<std::size_t>(frames), all = 0;
  MPI_Allreduce(&vis, &all, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, comm);
  t.visible = all;
  RenderOptions lopt = opt;
  lopt.stats = nullptr;
  lopt.legacy = true;
  t.legacy_fps = 1 / time_renders(comm, local, cam, frames, lopt, legacy);
  t.identical = fresh.rgb == legacy.rgb;
  t.image = std::move(fresh);
  // Split (b)'s floor: each rank composites its own splats over the whole image.
  opt.stats = nullptr;
  MPI_Barrier(comm);
  const double t1 = now();
  for (int f = 0; f < frames; ++f) gaussians::render(local, cam, opt);
  t.local_only_s = max_over(comm, now() - t1) / frames;
  return t;
}

std::string json_case(const char* name, long splats, const Camera& cam, int sh, const Timing& t) {
  char buf[1024];
  std::snprintf(buf, sizeof buf,
                "    {\"case\": \"%s\", \"splats\": %ld, \"sh_degree\": %d, \"width\": %d, "
                "\"height\": %d, \"visible\": %zu,\n     \"frames_per_s\": %.3f, "
                "\"legacy_frames_per_s\": %.3f, \"speedup\": %.2f, \"identical\": %s,\n"
                "     \"frame_s\": %.4f, \"phases_s\": {\"preprocess\": %.4f, \"exchange\": %.4f, "
                "\"sort\": %.4f, \"blend\": %.4f, \"gather\": %.4f},\n"
                "     \"split_b_lower_bound_s\": %.4f",
                name, splats, sh, cam.width, cam.height, t.visible, t.fps, t.legacy_fps,
                t.fps / t.legacy_fps, t.identical ? "true" : "false", t.frame_s, t.stats.preprocess,
                t.stats.exchange, t.stats.sort, t.stats.blend, t.stats.gather, t.local_only_s);
  return buf;
}

//! The GPU timing of a case (a JSON value): render_distributed on the device with the splats
//! uploaded every frame, then (one rank) with the splats kept on the device; its image against
//! the host's (`host`, rank 0).
std::string gpu_case(MPI_Comm comm, const SplatFrame& local, const Camera& cam, int frames,
                     const Image& host) {
  int rank = 0, ranks = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &ranks);
  int have = exec::use_device() ? 1 : 0, all = 0;
  MPI_Allreduce(&have, &all, 1, MPI_INT, MPI_MIN, comm);
  if (!all)
    return "\"skipped: " +
           (have ? std::string("a rank has no CUDA device") : exec::device_description()) + "\"";
  RenderOptions opt;
  RenderStats st;
  opt.stats = &st;
  Image img;
  const double frame_s = time_renders(comm, local, cam, frames, opt, img);
  const RenderStats ph = per_frame(comm, st, frames);
  double resident_s = 0;
#if defined(GEN4D_CUDA)
  if (ranks == 1) {  // the splats already on the device: projection, sort, blend, download
    gaussians::detail::DeviceRenderer& gpu = gaussians::detail::device_renderer();
    const gaussians::detail::View view(cam);
    gpu.upload(local);
    RenderOptions ropt;
    gpu.render(view, ropt);
    const double t0 = now();
    for (int f = 0; f < frames; ++f) gpu.render(view, ropt);
    resident_s = (now() - t0) / frames;
  }
#endif
  double psnr = 0, max_diff = 0;
  if (rank == 0) {
    psnr = gaussians::psnr(img, host);
    for (std::size_t i = 0; i < img.rgb.size(); ++i)
      max_diff = std::max(max_diff, static_cast<double>(std::fabs(img.rgb[i] - host.rgb[i])));
  }
  char buf[768];
  std::snprintf(buf, sizeof buf,
                "{\"device\": \"%s\", \"frames_per_s\": %.2f, \"resident_frames_per_s\": %s, "
                "\"phases_s\": {\"transfer\": %.4f, \"preprocess\": %.4f, \"sort\": %.4f, "
                "\"blend\": %.4f}, \"psnr_vs_host_db\": %.1f, \"max_diff_vs_host\": %.2e}",
                exec::device_description().c_str(), 1 / frame_s,
                resident_s > 0 ? std::to_string(1 / resident_s).c_str() : "null", ph.transfer,
                ph.preprocess, ph.sort, ph.blend, psnr, max_diff);
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
    cases += json_case("donut", static_cast<long>(n), cam, all.sh_degree, t) + "}";
    // Brute-force reference vs the tiled renderer on a small image, one thread, rank 0.
    if (rank == 0) {
      const Camera small = gaussians::framing_orbit(all, 96, 54, 40).at_frame(0);
      RenderOptions one;
      one.threads = 1;
      one.device = false;
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
    cases += json_case("synthetic", splats, cam, 3, t) +
             ",\n     \"gpu\": " + gpu_case(comm, local, cam, std::max(1, frames / 2), t.image) +
             "}";
  }
  if (rank == 0)
    std::printf(
        "{\n  \"benchmark\": \"render\",\n  \"ranks\": %d,\n  \"threads_per_rank\": %d,\n"
        "  \"baseline\": %s,\n  \"cases\": [\n%s\n  ]\n}\n",
        ranks, threads > 0 ? threads : exec::host_threads(), baseline.c_str(), cases.c_str());
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
        app.add_option("--threads", threads,
                       "Threads per rank (0: OMP_NUM_THREADS, else cores / ranks)")
            ->check(CLI::Range(0, 1024));
      },
      [&] { return gen4d::run(donut, splats, frames, threads); });
}
