# End-to-end checks of the gen4d executable: exit codes, one-line errors, untouched outputs,
# a SIGTERM / restart cycle at 2 ranks, the main job (the trained donut as MPM jelly, rendered)
# at 1, 2 and 4 ranks with identical images, and PhysGaussian configs (convert, a short run,
# bad input).
foreach(script cli_errors cli_sigterm_restart cli_splats cli_physgaussian
               cli_physgaussian_configs)
  gen4d_cli_test(${script})
endforeach()

# MPM runs end to end (sand column deck at a coarse cell size).
gen4d_cli_test(cli_mpm ARGS ${CMAKE_SOURCE_DIR}/inputs/mpm_sand.toml)

