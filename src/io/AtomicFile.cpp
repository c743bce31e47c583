#include "io/AtomicFile.hpp"

#include <sys/resource.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <algorithm>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>

#include "core/Error.hpp"

namespace gen4d::io {

std::string temp_beside(const std::string& path, bool with_pid) {
  const std::filesystem::path final_path(path);
  const std::string pid = with_pid ? "." + std::to_string(::getpid()) : "";
  return (final_path.parent_path() / ("." + final_path.filename().string() + pid + ".tmp"))
      .string();
}

std::string try_rename_into_place(const std::string& temp, const std::string& path) {
  if (std::rename(temp.c_str(), path.c_str()) == 0) return "";
  const std::string why = std::strerror(errno);
  std::remove(temp.c_str());
  return path + ": cannot rename " + temp + ": " + why;
}

std::string try_write_atomically(const std::string& path, std::string_view bytes,
                                 const std::string& temp) {
  std::FILE* file = std::fopen(temp.c_str(), "wb");
  if (file == nullptr) return path + ": cannot create " + temp + ": " + std::strerror(errno);
  const bool written = std::fwrite(bytes.data(), 1, bytes.size(), file) == bytes.size();
  const bool closed = std::fclose(file) == 0;
  if (!written || !closed) {
    const std::string why = std::strerror(errno);
    std::remove(temp.c_str());
    const std::string cause = write_failure_cause(temp, bytes.size());
    return path + ": cannot write " + temp + " (" + (cause.empty() ? why : cause) + ")";
  }
  return try_rename_into_place(temp, path);
}

std::string write_failure_cause(const std::string& path, std::uintmax_t needed) {
  namespace fs = std::filesystem;
  const fs::path file(path);
  const fs::path dir = file.has_parent_path() ? file.parent_path() : fs::path(".");
  std::error_code ec;
  const std::uintmax_t size = fs::exists(file, ec) ? fs::file_size(file, ec) : 0;
  struct rlimit limit {};
  if (::getrlimit(RLIMIT_FSIZE, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY &&
      size + std::max<std::uintmax_t>(needed, 1) > limit.rlim_cur) {
    return "the file size limit (ulimit -f) of " + std::to_string(limit.rlim_cur) + " bytes";
  }
  struct statvfs fsinfo {};
  if (::statvfs(dir.c_str(), &fsinfo) != 0) return "";
  const std::uintmax_t free_bytes =
      static_cast<std::uintmax_t>(fsinfo.f_bavail) * static_cast<std::uintmax_t>(fsinfo.f_frsize);
  if (free_bytes >= (needed > 0 ? needed : std::uintmax_t(1) << 20)) return "";
  return "no space left on device (" + std::to_string(free_bytes) + " bytes free in " +
         dir.string() + ")";
}

void write_atomically(const std::string& path, std::string_view bytes, bool with_pid) {
  const std::string error = try_write_atomically(path, bytes, temp_beside(path, with_pid));
  if (!error.empty()) throw RuntimeError(error);
}

}  // namespace gen4d::io
