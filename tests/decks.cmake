# Decks a user can trust: tables and keys a solver does not read refused by name, load curves,
# impossible inputs, the cylinder primitive, [[collider]] under the MPM, particles at the grid
# walls, and what --overwrite clears.
gen4d_test(decks SOURCES test_decks.cpp LIBS gen4d_geometry gen4d_mpm RANKS 1)
gen4d_test(decks_runs SOURCES test_decks_runs.cpp LIBS gen4d_elastogen gen4d_mpm RANKS 1 2 4)
gen4d_cli_test(cli_decks)
