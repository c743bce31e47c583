//! Reads TOML decks (plus --set overrides) into a validated gen4d::Config.
#pragma once

#include <string>
#include <vector>

#include "core/Config.hpp"

namespace gen4d {

//! Reads and validates the deck at `path`, applying `overrides` ("key=value" strings from
//! `--set`) in order. Relative mesh/VDB paths resolve against the deck's folder.
//! Throws InputError (one line: file, line, key) on any bad input.
Config load_deck(const std::string& path, const std::vector<std::string>& overrides = {});

//! Same as load_deck for deck text already in memory. `source_name` is what messages show
//! (e.g. "<embedded default>"); `base_dir` resolves relative mesh/VDB paths.
//! parse_deck(cfg.text, ...) reproduces `cfg`, which is how restarts recover their deck.
Config parse_deck(const std::string& text, const std::string& source_name,
                  const std::string& base_dir, const std::vector<std::string>& overrides = {});

}  // namespace gen4d
