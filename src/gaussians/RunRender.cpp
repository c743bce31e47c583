#include "gaussians/RunRender.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <vector>

#include "core/Error.hpp"
#include "parallel/Collective.hpp"
#include "gaussians/Kinematics.hpp"
#include "gaussians/Video.hpp"

namespace gen4d::gaussians {

namespace fs = std::filesystem;

std::string frame_png_name(long index) {
  return fmt::format("frame_{:06d}.png", index);
}

long frame_png_index(const std::string& name) {
  const std::string head = "frame_", tail = ".png";
  if (name.size() <= head.size() + tail.size() || name.rfind(head, 0) != 0 ||
      name.compare(name.size() - tail.size(), tail.size(), tail) != 0)
    return -1;
  const std::string digits = name.substr(head.size(), name.size() - head.size() - tail.size());
  if (digits.size() > 12 || !std::all_of(digits.begin(), digits.end(),
                                         [](unsigned char c) { return std::isdigit(c) != 0; }))
    return -1;
  return std::stol(digits);
}

Camera orbit_camera(const RenderConfig& r, long index) {
  OrbitCamera orbit;
  orbit.center = r.center;
  orbit.up = r.up;
  orbit.azimuth = r.azimuth;
  orbit.elevation = r.elevation;
  orbit.radius = r.radius;
  orbit.d_azimuth = r.d_azimuth;
  orbit.d_elevation = r.d_elevation;
  orbit.d_radius = r.d_radius;
  orbit.fov_y_degrees = r.fov_y;
  orbit.width = r.width;
  orbit.height = r.height;
  return orbit.at_frame(index);
}

RunRenderer::RunRenderer(MPI_Comm comm, const RenderConfig& r) : comm_(comm), cfg_(r) {
  MPI_Comm_rank(comm_, &rank_);
  if (cfg_.camera == "auto") cfg_.radius = 0;  // set by frame_object
  if (cfg_.camera != "orbit" && cfg_.camera != "auto") fixed_ = read_camera_spec(cfg_.camera);
  for (int c = 0; c < 3; ++c) options_.background[c] = static_cast<float>(cfg_.background[c]);
}

void RunRenderer::frame_object(const SplatSet& splats, const std::array<double, 3>& lo,
                               const std::array<double, 3>& hi) {
  if (cfg_.camera != "auto") return;
  std::array<double, 3> a = lo, b = hi;
  if (splats.size() > 0) {
    const auto box = central_box(rest_frame(splats));
    for (int k = 0; k < 3; ++k) {
      const bool other = lo[k] <= hi[k];
      a[k] = other ? std::min(lo[k], box[0][k]) : box[0][k];
      b[k] = other ? std::max(hi[k], box[1][k]) : box[1][k];
    }
  }
  for (int k = 0; k < 3; ++k)
    if (!(a[k] <= b[k])) throw InputError("render.camera = \"auto\": there is no object to frame");
  const OrbitCamera o = framing_orbit(a, b, cfg_.width, cfg_.height, cfg_.fov_y, cfg_.up);
  cfg_.center = o.center;
  cfg_.radius = o.radius;
}

Camera RunRenderer::camera(long index) const {
  if (cfg_.camera == "auto" && cfg_.radius <= 0)
    throw std::logic_error("RunRenderer: the auto camera has not framed the object");
  return cfg_.camera == "orbit" || cfg_.camera == "auto" ? orbit_camera(cfg_, index) : fixed_;
}

void RunRenderer::open(const std::string& out_dir, long keep_up_to) {
  out_dir_ = out_dir;
  png_dir_ = (fs::path(out_dir) / "png").string();
  parallel::on_rank0(comm_, png_dir_ + ": cannot prepare the image folder", [&] {
    std::error_code ec;
    fs::create_directories(png_dir_, ec);
    if (ec) throw RuntimeError(png_dir_ + ": cannot create directory: " + ec.message());
    std::vector<fs::path> doomed;
    for (const auto& entry : fs::directory_iterator(png_dir_, ec))
      if (frame_png_index(entry.path().filename().string()) > keep_up_to)
        doomed.push_back(entry.path());
    if (ec) throw RuntimeError(png_dir_ + ": cannot list: " + ec.message());
    for (const auto& p : doomed)
      if (!fs::remove(p, ec) && ec)
        throw RuntimeError(p.string() + ": cannot remove: " + ec.message());
  });
}

void RunRenderer::render(long index, const SplatFrame& local) {
  const Image image = render_distributed(comm_, local, camera(index), options_);
  parallel::on_rank0(comm_, png_dir_ + ": image write failed", [&] {
    write_image_png((fs::path(png_dir_) / frame_png_name(index)).string(), image);
  });
  ++images_;
}

void RunRenderer::finish(double frame_interval) {
  if (!cfg_.mp4 || png_dir_.empty()) return;
  // Real time where that is a sensible frame rate, else the nearer bound of [1, 60].
  const double fps = std::clamp(frame_interval > 0 ? 1.0 / frame_interval : 60.0, 1.0, 60.0);
  const std::string mp4 = (fs::path(out_dir_) / "render.mp4").string();
  // assemble_mp4 notes itself what it wrote, or that ffmpeg is missing.
  parallel::on_rank0(comm_, mp4 + ": video assembly failed",
                     [&] { assemble_mp4(png_dir_, fps, mp4); });
}

}  // namespace gen4d::gaussians
