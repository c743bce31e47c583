# The scaling study (jobs/scaling/study.sh) at its tiny size at 1 and 2 ranks (the full
# study adds 4 oversubscribed ranks): every measurement, the CSV files, the model fit, the
# projection and the plots are produced and well-formed (jobs/scaling/check.py). Timings are
# not asserted.
# The distribution's python3, which has numpy and matplotlib (python3-matplotlib).
find_program(GEN4D_SYSTEM_PYTHON NAMES python3 PATHS /usr/bin NO_DEFAULT_PATH)
if(GEN4D_SYSTEM_PYTHON AND TARGET gen4d AND TARGET bench_mpm AND TARGET bench_render
   AND TARGET bench_mpi)
  add_test(NAME scaling_study_tiny
           COMMAND bash -c "rm -rf \"$1\" && bash \"$2/jobs/scaling/study.sh\" --size tiny --ranks '1 2' --out \"$1\" && \"$3\" \"$2/jobs/scaling/check.py\" \"$1\" '1 2'"
                   scaling ${CMAKE_CURRENT_BINARY_DIR}/scratch/scaling_study_tiny
                   ${CMAKE_SOURCE_DIR} ${GEN4D_SYSTEM_PYTHON})
  set_tests_properties(scaling_study_tiny PROPERTIES
    ENVIRONMENT "${GEN4D_TEST_ENV};GEN4D=$<TARGET_FILE:gen4d>;BENCH_MPM=$<TARGET_FILE:bench_mpm>;BENCH_RENDER=$<TARGET_FILE:bench_render>;BENCH_MPI=$<TARGET_FILE:bench_mpi>;MPIEXEC=${MPIEXEC_EXECUTABLE};PYTHON=${GEN4D_SYSTEM_PYTHON}"
    PROCESSORS 2 TIMEOUT 300)
endif()
