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

# NeuralMTL twin: the same cantilever with the shipped Neo-Hookean network beside the analytic
# target, both within 2 % of Newton (full run over 3 laws x 3 nu: validate_cantilever --neural).
if(TARGET validate_cantilever)
  foreach(np 1 2)
    add_test(NAME validate_cantilever_neural_quick_np${np}
             COMMAND ${MPIEXEC_EXECUTABLE} ${MPIEXEC_NUMPROC_FLAG} ${np} --oversubscribe
                     $<TARGET_FILE:validate_cantilever> --steps 20 --neural --models neo_hookean
                     --nus 0.3 --weights ${CMAKE_SOURCE_DIR}/inputs/models/mtl/{model}_{nu}.h5)
    set_tests_properties(validate_cantilever_neural_quick_np${np} PROPERTIES
                         ENVIRONMENT "${GEN4D_TEST_ENV}" PROCESSORS ${np} TIMEOUT 600)
  endforeach()
endif()

# Small twin of the kernel benchmark: it must run and print its JSON at 1 and 2 ranks.
if(TARGET bench_elastogen)
  foreach(np 1 2)
    add_test(NAME bench_elastogen_quick_np${np}
             COMMAND ${MPIEXEC_EXECUTABLE} ${MPIEXEC_NUMPROC_FLAG} ${np} --oversubscribe
                     $<TARGET_FILE:bench_elastogen> --cells 8 --sweeps 5 --stream-n 1000000)
    set_tests_properties(bench_elastogen_quick_np${np} PROPERTIES
                         ENVIRONMENT "${GEN4D_TEST_ENV}" PROCESSORS ${np} TIMEOUT 300
                         PASS_REGULAR_EXPRESSION "\"node_updates_per_s\": [0-9]")
  endforeach()
endif()
gen4d_test(frequency SOURCES test_frequency.cpp LIBS gen4d_elastogen RANKS 1)
gen4d_test(contact SOURCES test_contact.cpp LIBS gen4d_elastogen RANKS 1 2 4)

# Small twin of the convergence validation driver (full run: see drivers/validation).
if(TARGET validate_convergence)
  foreach(np 1 2)
    add_test(NAME validate_convergence_quick_np${np}
             COMMAND ${MPIEXEC_EXECUTABLE} ${MPIEXEC_NUMPROC_FLAG} ${np} --oversubscribe
                     $<TARGET_FILE:validate_convergence> --steps 8 --voxel 0.05 --plain-cap 400)
    set_tests_properties(validate_convergence_quick_np${np} PROPERTIES
                         ENVIRONMENT "${GEN4D_TEST_ENV}" PROCESSORS ${np} TIMEOUT 600)
  endforeach()
endif()
