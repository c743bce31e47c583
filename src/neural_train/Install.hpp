//! Lets decks with material.target = "neural" and no weight file generate their network:
//! installs the diffusion generator (with its on-disk cache) as the solver's weight source.
#pragma once

#include <string>

namespace gen4d::neural_train {

//! Cache folder for generated networks: $GEN4D_CACHE_DIR, else $XDG_CACHE_HOME/gen4d, else
//! $HOME/.cache/gen4d, else ./.gen4d-cache.
std::string default_cache_dir();

//! Calls neural::set_weight_generator with cached_material(default_cache_dir(), law, nu,
//! default_generator_path()). Programs linking LibTorch call it once at start-up.
void install_weight_generator();

}  // namespace gen4d::neural_train
