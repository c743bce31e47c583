# Decks a user can trust: tables and keys a solver does not read refused by name, load curves,
# impossible inputs, the cylinder primitive, [[collider]] under the MPM, particles at the grid
# walls, and what --overwrite clears.
gen4d_test(decks SOURCES test_decks.cpp LIBS gen4d_geometry gen4d_mpm RANKS 1)
gen4d_test(decks_runs SOURCES test_decks_runs.cpp LIBS gen4d_elastogen gen4d_mpm RANKS 1 2 4)
if(TARGET gen4d)
  add_test(NAME cli_decks
           COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/cli_decks.sh $<TARGET_FILE:gen4d>
                   ${MPIEXEC_EXECUTABLE} ${CMAKE_CURRENT_BINARY_DIR}/scratch/cli_decks)
  set_tests_properties(cli_decks PROPERTIES ENVIRONMENT "${GEN4D_TEST_ENV}" PROCESSORS 2
                       TIMEOUT 600)
endif()
