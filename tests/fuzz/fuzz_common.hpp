//! Shared by the libFuzzer targets: the input as a per-process temporary file (for readers that
//! take a path) and the errors a reader may throw on bad input.
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>

#include "core/Error.hpp"

namespace gen4d::fuzz {

//! A folder of this process under the temporary directory, removed at exit.
inline const std::filesystem::path& scratch_dir() {
  struct Dir {
    std::filesystem::path path;
    Dir() {
      path = std::filesystem::temp_directory_path() /
             ("gen4d-fuzz-" + std::to_string(static_cast<long>(::getpid())));
      std::filesystem::create_directories(path);
    }
    ~Dir() {
      std::error_code ec;
      std::filesystem::remove_all(path, ec);
    }
  };
  static const Dir dir;
  return dir.path;
}

//! Writes the input to scratch_dir()/name (overwriting) and returns the path.
inline std::string write_input(const std::string& name, const std::uint8_t* data,
                               std::size_t size) {
  const std::string path = (scratch_dir() / name).string();
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  out.close();
  if (!out) {
    std::fprintf(stderr, "fuzz: cannot write %s\n", path.c_str());
    std::abort();
  }
  return path;
}

//! Runs `read`; the project's own errors for bad input are the expected outcome. Any other
//! exception escapes, and libFuzzer reports it as a crash: a reader must turn every bad input
//! into an InputError or RuntimeError naming the file.
template <class F>
void expect_clean_errors(F&& read) {
  try {
    read();
  } catch (const gen4d::InputError&) {
  } catch (const gen4d::RuntimeError&) {
  }
}

}  // namespace gen4d::fuzz
