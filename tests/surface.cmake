# Surface output: PLY/OBJ files and previews (io), the embedded surface and its sequence (elastogen).
gen4d_test(io_surface SOURCES test_io_surface.cpp LIBS gen4d_io PNG::PNG RANKS 1)
gen4d_test(surface SOURCES test_surface.cpp LIBS gen4d_elastogen RANKS 1 2 4)
if(TARGET gen4d)
  add_test(NAME cli_surface
           COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/cli_surface.sh $<TARGET_FILE:gen4d>
                   ${MPIEXEC_EXECUTABLE} ${CMAKE_CURRENT_BINARY_DIR}/scratch/cli_surface)
  set_tests_properties(cli_surface PROPERTIES ENVIRONMENT "${GEN4D_TEST_ENV}" PROCESSORS 2
                       TIMEOUT 600)
endif()
