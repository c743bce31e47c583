gen4d_test(elastogen SOURCES test_elastogen.cpp LIBS gen4d_elastogen RANKS 1 2 4)
gen4d_test(cantilever SOURCES test_cantilever.cpp LIBS gen4d_elastogen RANKS 1)
gen4d_test(stencil SOURCES test_stencil.cpp LIBS gen4d_elastogen RANKS 1)

# Small twin of the cantilever validation driver (full run: see drivers/validation).
if(TARGET validate_cantilever)
  foreach(np 1 2)
    add_test(NAME validate_cantilever_quick_np${np}
             COMMAND ${MPIEXEC_EXECUTABLE} ${MPIEXEC_NUMPROC_FLAG} ${np} --oversubscribe
                     $<TARGET_FILE:validate_cantilever> --steps 10)
    set_tests_properties(validate_cantilever_quick_np${np} PROPERTIES
                         ENVIRONMENT "${GEN4D_TEST_ENV}" PROCESSORS ${np} TIMEOUT 600)
  endforeach()
endif()
