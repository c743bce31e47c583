# Small twins of the validation drivers and benchmarks (full runs: see drivers/ and README).
# Each twin runs its driver at a reduced size and must meet the driver's own target.
function(gen4d_driver_twin name target ranks)
  cmake_parse_arguments(D "" "PASS" "ARGS" ${ARGN})
  if(NOT TARGET ${target})
    return()
  endif()
  foreach(np IN LISTS ranks)
    add_test(NAME ${name}_np${np}
             COMMAND ${MPIEXEC_EXECUTABLE} ${MPIEXEC_NUMPROC_FLAG} ${np} --oversubscribe
                     $<TARGET_FILE:${target}> ${D_ARGS})
    set_tests_properties(${name}_np${np} PROPERTIES ENVIRONMENT "${GEN4D_TEST_ENV}"
                         PROCESSORS ${np} TIMEOUT 600)
    if(D_PASS)
      set_tests_properties(${name}_np${np} PROPERTIES PASS_REGULAR_EXPRESSION "${D_PASS}")
    endif()
  endforeach()
endfunction()

# Static cantilever vs Euler-Bernoulli at H/2 and H/4 (3 % target at H/4), both solvers.
gen4d_driver_twin(validate_analytic_quick validate_analytic "1;2"
                  ARGS --static-levels 2,4 --skip-frequency)
# Large time step on a coarse soft beam: stability table and ElastoGen vs Newton <= 1 %.
gen4d_driver_twin(validate_timestep_quick validate_timestep "1;2"
                  ARGS --voxel 0.025 --end-time 0.1 --skip-fine)
# ElastoGen vs Newton time per frame on a small beam: must print its JSON.
gen4d_driver_twin(bench_solvers_quick bench_solvers "1;2" ARGS --cells 4 --frames 3
                  PASS "\"speedup_elastogen_over_newton\": [0-9]")
