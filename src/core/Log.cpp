#include "core/Log.hpp"

#include <cstdio>

namespace gen4d::log {
namespace {
int g_rank = 0;
bool g_quiet = false;
}  // namespace

void set_rank(int r) {
  g_rank = r;
}
int rank() {
  return g_rank;
}
void set_quiet(bool q) {
  g_quiet = q;
}

void info_str(const std::string& msg) {
  if (g_rank != 0 || g_quiet) return;
  std::fprintf(stdout, "%s\n", msg.c_str());
  std::fflush(stdout);
}
void warn_str(const std::string& msg) {
  std::fprintf(stderr, "gen4d: warning [rank %d]: %s\n", g_rank, msg.c_str());
}
void error_str(const std::string& msg) {
  std::fprintf(stderr, "gen4d: error: %s\n", msg.c_str());
  std::fflush(stderr);
}

}  // namespace gen4d::log
