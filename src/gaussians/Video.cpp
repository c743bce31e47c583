#include "gaussians/Video.hpp"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <vector>

#include "core/Error.hpp"
#include "core/Log.hpp"

namespace gen4d::gaussians {
namespace fs = std::filesystem;

namespace {

std::string quoted(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

//! Whether `ffmpeg -encoders` lists `name`.
bool has_encoder(const std::string& ffmpeg, const std::string& name) {
  const std::string cmd = quoted(ffmpeg) + " -hide_banner -encoders 2>/dev/null";
  std::unique_ptr<FILE, int (*)(FILE*)> pipe(::popen(cmd.c_str(), "r"), ::pclose);
  if (!pipe) return false;
  std::array<char, 512> buf{};
  while (std::fgets(buf.data(), buf.size(), pipe.get())) {
    std::istringstream line(buf.data());
    std::string flags, encoder;
    if (line >> flags >> encoder && encoder == name) return true;
  }
  return false;
}

}  // namespace

std::string find_ffmpeg() {
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path ? path : "");
  for (std::string dir; std::getline(dirs, dir, ':');) {
    if (dir.empty()) continue;
    const fs::path candidate = fs::path(dir) / "ffmpeg";
    if (::access(candidate.c_str(), X_OK) == 0 && !fs::is_directory(candidate))
      return candidate.string();
  }
  return "";
}

std::string assemble_mp4(const std::string& png_dir, double fps, const std::string& out_mp4) {
  if (!(fps > 0) || !std::isfinite(fps))
    throw InputError(out_mp4 + ": the video's frame rate must be positive");
  std::vector<std::string> pngs;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(png_dir, ec))
    if (e.is_regular_file() && e.path().extension() == ".png") pngs.push_back(e.path().string());
  if (ec) throw InputError(png_dir + ": cannot list the PNG directory: " + ec.message());
  if (pngs.empty()) throw InputError(png_dir + ": no PNG files to assemble into a video");
  std::sort(pngs.begin(), pngs.end());
  return assemble_mp4(pngs, fps, out_mp4);
}

std::string assemble_mp4(const std::vector<std::string>& pngs, double fps,
                         const std::string& out_mp4) {
  if (!(fps > 0) || !std::isfinite(fps))
    throw InputError(out_mp4 + ": the video's frame rate must be positive");
  if (pngs.empty()) throw InputError(out_mp4 + ": no PNG files to assemble into a video");
  std::error_code ec;
  const std::string ffmpeg = find_ffmpeg();
  if (ffmpeg.empty()) {
    log::info("ffmpeg is not on PATH: no video {} (the PNG files are in {})", out_mp4,
              fs::path(pngs.front()).parent_path().string());
    return "";
  }
  const fs::path out(out_mp4);
  const fs::path dir = out.has_parent_path() ? out.parent_path() : fs::path(".");
  const fs::path list = dir / ("." + out.filename().string() + ".frames.txt");
  const fs::path temp = dir / ("." + out.filename().string() + ".tmp");
  {
    std::ofstream f(list);
    for (const auto& p : pngs)
      f << "file " << quoted(fs::absolute(p).string()) << "\nduration " << 1.0 / fps << "\n";
    // The concat demuxer drops the last duration unless the last file is listed again (the
    // repeat itself is cut by -frames:v).
    f << "file " << quoted(fs::absolute(pngs.back()).string()) << "\n";
    if (!f) throw RuntimeError(list.string() + ": cannot write the frame list for ffmpeg");
  }
  const std::string codec = has_encoder(ffmpeg, "libx264") ? "libx264" : "mpeg4";
  char rate[32];
  std::snprintf(rate, sizeof rate, "%.6g", fps);
  const std::string cmd =
      quoted(ffmpeg) + " -hide_banner -loglevel error -y -f concat -safe 0 -i " +
      quoted(list.string()) + " -vf 'scale=trunc(iw/2)*2:trunc(ih/2)*2,format=yuv420p' -r " + rate +
      " -frames:v " + std::to_string(pngs.size()) + " -c:v " + codec +
      (codec == "mpeg4" ? " -q:v 3" : " -crf 18") + " -f mp4 " + quoted(temp.string());
  const int rc = std::system(cmd.c_str());
  fs::remove(list, ec);
  if (rc != 0) {
    fs::remove(temp, ec);
    throw RuntimeError(out_mp4 + ": ffmpeg failed (exit status " + std::to_string(rc) + ")");
  }
  fs::rename(temp, out, ec);
  if (ec) {
    fs::remove(temp, ec);
    throw RuntimeError(out_mp4 + ": cannot rename the video into place: " + ec.message());
  }
  log::info("wrote {} ({} frames, {})", out_mp4, pngs.size(), codec);
  return out_mp4;
}

}  // namespace gen4d::gaussians
