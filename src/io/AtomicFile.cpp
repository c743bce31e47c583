#include "io/AtomicFile.hpp"

#include <unistd.h>

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
    std::remove(temp.c_str());
    return path + ": cannot write " + temp + " (disk full?)";
  }
  return try_rename_into_place(temp, path);
}

void write_atomically(const std::string& path, std::string_view bytes, bool with_pid) {
  const std::string error = try_write_atomically(path, bytes, temp_beside(path, with_pid));
  if (!error.empty()) throw RuntimeError(error);
}

}  // namespace gen4d::io
