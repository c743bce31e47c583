//! Error types that map to the CLI's exit codes (2 bad input, 1 runtime failure).
#pragma once

#include <stdexcept>
#include <string>

namespace gen4d {

//! Bad user input (deck, mesh, VDB, checkpoint, command line). Exit code 2.
//! The message is one line naming the file, and where known the line and key.
class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& what) : std::runtime_error(what) {}
};

//! A failure while running (solver divergence, I/O failure). Exit code 1.
class RuntimeError : public std::runtime_error {
 public:
  explicit RuntimeError(const std::string& what) : std::runtime_error(what) {}
};

}  // namespace gen4d
