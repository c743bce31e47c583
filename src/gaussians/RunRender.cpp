#include "gaussians/RunRender.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <utility>
#include <vector>

#include "core/Error.hpp"
#include "parallel/Collective.hpp"
#include "gaussians/Kinematics.hpp"
#include "gaussians/Ply.hpp"
#include "gaussians/Video.hpp"
#include "parallel/Comm.hpp"

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

std::string physgaussian_png_name(long image) {
  const std::string name = fmt::format("{}.png", image);
  return std::string(name.size() < 8 ? 8 - name.size() : 0, '0') + name;
}

long physgaussian_png_index(const std::string& name) {
  const std::string tail = ".png";
  if (name.size() < 8 || name.size() > 16 ||
      name.compare(name.size() - tail.size(), tail.size(), tail) != 0)
    return -1;
  const std::string digits = name.substr(0, name.size() - tail.size());
  if (!std::all_of(digits.begin(), digits.end(),
                   [](unsigned char c) { return std::isdigit(c) != 0; }))
    return -1;
  const long image = std::stol(digits);
  return physgaussian_png_name(image) == name ? image : -1;
}

std::string frame_image_name(const std::string& layout, long index) {
  if (layout == "physgaussian") return index >= 1 ? physgaussian_png_name(index - 1) : "";
  return (fs::path("png") / frame_png_name(index)).string();
}

long frame_image_index(const std::string& layout, const std::string& name) {
  const fs::path p(name);
  if (layout == "physgaussian") {
    if (p.has_parent_path()) return -1;
    const long image = physgaussian_png_index(name);
    return image < 0 ? -1 : image + 1;
  }
  return p.parent_path() == "png" ? frame_png_index(p.filename().string()) : -1;
}

SplatFrame merge_frames(const SplatFrame& a, const SplatFrame& b) {
  if (b.size() == 0) return a;
  if (a.size() == 0) return b;
  const int degree = std::max(a.sh_degree, b.sh_degree);
  const bool rotate = !a.sh_rotation.empty() || !b.sh_rotation.empty();
  SplatFrame out;
  out.sh_degree = degree;
  const std::size_t want = 3 * static_cast<std::size_t>(sh_coefficients(degree));
  for (const SplatFrame* f : {&a, &b}) {
    out.position.insert(out.position.end(), f->position.begin(), f->position.end());
    out.covariance.insert(out.covariance.end(), f->covariance.begin(), f->covariance.end());
    out.opacity.insert(out.opacity.end(), f->opacity.begin(), f->opacity.end());
    const std::size_t have = 3 * static_cast<std::size_t>(f->coefficients());
    for (std::size_t i = 0; i < f->size(); ++i) {
      const auto first = f->sh.begin() + static_cast<std::ptrdiff_t>(i * have);
      out.sh.insert(out.sh.end(), first, first + static_cast<std::ptrdiff_t>(have));
      out.sh.insert(out.sh.end(), want - have, 0.0f);
    }
    if (!rotate) continue;
    if (!f->sh_rotation.empty()) {
      out.sh_rotation.insert(out.sh_rotation.end(), f->sh_rotation.begin(), f->sh_rotation.end());
    } else {
      for (std::size_t i = 0; i < f->size(); ++i)
        out.sh_rotation.insert(out.sh_rotation.end(), {1, 0, 0, 0, 1, 0, 0, 0, 1});
    }
  }
  return out;
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
  rank_ = parallel::rank(comm_);
  if (cfg_.camera == "auto") cfg_.radius = 0;  // set by frame_object
  if (cfg_.camera != "orbit" && cfg_.camera != "auto") fixed_ = read_camera_spec(cfg_.camera);
  for (int c = 0; c < 3; ++c) options_.background[c] = static_cast<float>(cfg_.background[c]);
  if (!cfg_.scenery.empty()) {
    // Every rank reads and checks the file (the same InputError everywhere) and keeps the
    // contiguous block [r n / P, (r + 1) n / P) of its splats; the image does not depend on
    // how the splats are distributed.
    SplatSet all;
    try {
      all = read_splats_ply(cfg_.scenery);
    } catch (const InputError& e) {
      throw InputError(std::string("render.scenery: ") + e.what());
    }
    const std::size_t n = all.size(), P = static_cast<std::size_t>(parallel::size(comm_));
    const std::size_t r = static_cast<std::size_t>(rank_);
    const std::size_t begin = n * r / P, end = n * (r + 1) / P;
    SplatSet mine;
    mine.sh_degree = all.sh_degree;
    const std::size_t K = 3 * static_cast<std::size_t>(all.coefficients());
    auto take = [&](const std::vector<double>& from, std::size_t width, std::vector<double>& to) {
      to.assign(from.begin() + static_cast<std::ptrdiff_t>(begin * width),
                from.begin() + static_cast<std::ptrdiff_t>(end * width));
    };
    take(all.position, 3, mine.position);
    take(all.scale, 3, mine.scale);
    take(all.rotation, 4, mine.rotation);
    take(all.opacity, 1, mine.opacity);
    take(all.sh, K, mine.sh);
    scenery_ = rest_frame(mine);
  }
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
  const fs::path folder = fs::path(frame_image_name(cfg_.layout, 1)).parent_path();
  png_dir_ = folder.empty() ? out_dir : (fs::path(out_dir) / folder).string();
  parallel::on_rank0(comm_, png_dir_ + ": cannot prepare the image folder", [&] {
    std::error_code ec;
    fs::create_directories(png_dir_, ec);
    if (ec) throw RuntimeError(png_dir_ + ": cannot create directory: " + ec.message());
    std::vector<fs::path> doomed;
    for (const auto& entry : fs::directory_iterator(png_dir_, ec))
      if (frame_image_index(cfg_.layout, (folder / entry.path().filename()).string()) > keep_up_to)
        doomed.push_back(entry.path());
    if (ec) throw RuntimeError(png_dir_ + ": cannot list: " + ec.message());
    for (const auto& p : doomed)
      if (!fs::remove(p, ec) && ec)
        throw RuntimeError(p.string() + ": cannot remove: " + ec.message());
  });
}

void RunRenderer::render(long index, const SplatFrame& local) {
  const std::string name = frame_image_name(cfg_.layout, index);
  if (name.empty()) return;
  const Image image =
      scenery_.size() == 0
          ? render_distributed(comm_, local, camera(index), options_)
          : render_distributed(comm_, merge_frames(local, scenery_), camera(index), options_);
  parallel::on_rank0(comm_, png_dir_ + ": image write failed",
                     [&] { write_image_png((fs::path(out_dir_) / name).string(), image); });
  ++images_;
}

double RunRenderer::fps(double frame_interval) const {
  if (cfg_.fps > 0) return cfg_.fps;
  // Real time where that is a sensible frame rate, else the nearer bound of [1, 60].
  return std::clamp(frame_interval > 0 ? 1.0 / frame_interval : 60.0, 1.0, 60.0);
}

void RunRenderer::finish(double frame_interval) {
  if (!cfg_.mp4 || png_dir_.empty()) return;
  const std::string mp4 =
      (fs::path(out_dir_) / (cfg_.layout == "physgaussian" ? "output.mp4" : "render.mp4")).string();
  // assemble_mp4 notes itself what it wrote, or that ffmpeg is missing.
  parallel::on_rank0(comm_, mp4 + ": video assembly failed", [&] {
    // The layout's images (a restart's included) in frame order, not name order.
    const fs::path folder = fs::path(frame_image_name(cfg_.layout, 1)).parent_path();
    std::vector<std::pair<long, std::string>> images;
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(png_dir_, ec)) {
      const long index =
          frame_image_index(cfg_.layout, (folder / entry.path().filename()).string());
      if (index >= 0) images.emplace_back(index, entry.path().string());
    }
    if (ec) throw RuntimeError(png_dir_ + ": cannot list the images: " + ec.message());
    std::sort(images.begin(), images.end());
    std::vector<std::string> files;
    for (const auto& image : images) files.push_back(image.second);
    assemble_mp4(files, fps(frame_interval), mp4);
  });
}

}  // namespace gen4d::gaussians
