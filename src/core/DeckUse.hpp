//! Which tables and keys of a deck each of its users reads: a table or key a user does not
//! read is refused by name, never silently ignored (inputs/README.md, "Who reads what").
#pragma once

#include <string>

#include "core/Config.hpp"

namespace gen4d {

//! A reader of decks: a solver of `gen4d run` (solver.method) or `gen4d diagnose`.
enum class DeckUser { Elastogen, Newton, Mpm, Diagnose };

//! The solver that runs `c` (its solver.method).
DeckUser run_user(const Config& c);

//! Throws InputError ("FILE:LINE: ...", naming the table or key and what to use instead) at
//! the first table or key of `c` that `user` does not read. Keys a user does not read but
//! that keep a deck shareable between commands (the ElastoGen solver's settings under the
//! Newton reference, how a run is written under gen4d diagnose) are accepted with one
//! warning line on rank 0 instead.
void check_deck_use(const Config& c, DeckUser user);

}  // namespace gen4d
