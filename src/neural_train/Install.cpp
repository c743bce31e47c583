#include "neural_train/Install.hpp"

#include <cstdlib>
#include <filesystem>

#include "neural/WeightSource.hpp"
#include "neural_train/Generate.hpp"

namespace gen4d::neural_train {

std::string default_cache_dir() {
  namespace fs = std::filesystem;
  if (const char* d = std::getenv("GEN4D_CACHE_DIR"); d && *d) return d;
  if (const char* d = std::getenv("XDG_CACHE_HOME"); d && *d)
    return (fs::path(d) / "gen4d").string();
  if (const char* d = std::getenv("HOME"); d && *d)
    return (fs::path(d) / ".cache" / "gen4d").string();
  return ".gen4d-cache";
}

void install_weight_generator() {
  neural::set_weight_generator([](const std::string& law, double nu, double) {
    return cached_material(default_cache_dir(), law, nu, default_generator_path());
  });
}

}  // namespace gen4d::neural_train
