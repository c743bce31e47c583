# End-to-end checks of the gen4d executable: exit codes, one-line errors, untouched outputs,
# a SIGTERM / restart cycle at 2 ranks, the main job (the trained donut as MPM jelly, rendered)
# at 1, 2 and 4 ranks with identical images, and PhysGaussian configs (convert, a short run,
# bad input).
if(TARGET gen4d)
  foreach(script cli_errors cli_sigterm_restart cli_splats cli_physgaussian
                 cli_physgaussian_configs)
    add_test(NAME ${script}
             COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/${script}.sh $<TARGET_FILE:gen4d>
                     ${MPIEXEC_EXECUTABLE} ${CMAKE_CURRENT_BINARY_DIR}/scratch/${script})
    set_tests_properties(${script} PROPERTIES ENVIRONMENT "${GEN4D_TEST_ENV}" PROCESSORS 2
                         TIMEOUT 600)
  endforeach()
endif()

# MPM runs end to end (sand column deck at a coarse cell size).
if(TARGET gen4d)
  add_test(NAME cli_mpm
           COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/cli_mpm.sh $<TARGET_FILE:gen4d>
                   ${MPIEXEC_EXECUTABLE} ${CMAKE_CURRENT_BINARY_DIR}/scratch/cli_mpm
                   ${CMAKE_SOURCE_DIR}/inputs/mpm_sand.toml)
  set_tests_properties(cli_mpm PROPERTIES ENVIRONMENT "${GEN4D_TEST_ENV}" PROCESSORS 2
                       TIMEOUT 600)
endif()

