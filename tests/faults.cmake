# Injected faults: kill -9 of a rank during a checkpoint write, a full disk during frame and
# checkpoint writes, ranks that die or hang mid-step, a deck larger than the machine's
# memory; and the MPI error handler and watchdog in a small probe.
foreach(script cli_faults_checkpoint_kill cli_faults_disk_full cli_faults_rank_death
               cli_faults_memory)
  gen4d_cli_test(${script} TIMEOUT 300)
endforeach()
set_tests_properties(cli_faults_disk_full PROPERTIES SKIP_RETURN_CODE 77)

add_executable(faults_probe faults_probe.cpp)
target_link_libraries(faults_probe PRIVATE gen4d_parallel)
gen4d_cli_test(cli_faults_probe ARGS $<TARGET_FILE:faults_probe> TIMEOUT 300)

gen4d_test(memory_estimate SOURCES test_memory_estimate.cpp LIBS gen4d_core RANKS 1 2)
gen4d_test(faults_io SOURCES test_faults_io.cpp LIBS gen4d_io RANKS 1 2)
