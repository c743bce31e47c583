gen4d_test(elastogen SOURCES test_elastogen.cpp LIBS gen4d_elastogen RANKS 1 2 4)
gen4d_test(cantilever SOURCES test_cantilever.cpp LIBS gen4d_elastogen RANKS 1)
gen4d_test(stencil SOURCES test_stencil.cpp LIBS gen4d_elastogen RANKS 1)

# Small twin of the cantilever validation driver (full run: see drivers/validation).
gen4d_driver_twin(validate_cantilever_quick validate_cantilever "1;2" ARGS --steps 10)

# NeuralMTL twin: the same cantilever with the shipped Neo-Hookean network beside the analytic
# target, both within 2 % of Newton (full run over 3 laws x 3 nu: validate_cantilever --neural).
gen4d_driver_twin(validate_cantilever_neural_quick validate_cantilever "1;2"
                  ARGS --steps 20 --neural --models neo_hookean --nus 0.3
                       --weights ${CMAKE_SOURCE_DIR}/inputs/models/mtl/{model}_{nu}.h5)

# Small twin of the kernel benchmark: it must run and print its JSON at 1 and 2 ranks.
gen4d_driver_twin(bench_elastogen_quick bench_elastogen "1;2" TIMEOUT 300
                  ARGS --cells 8 --sweeps 5 --stream-n 1000000
                  PASS "\"node_updates_per_s\": [0-9]")
gen4d_test(frequency SOURCES test_frequency.cpp LIBS gen4d_elastogen RANKS 1)
gen4d_test(contact SOURCES test_contact.cpp LIBS gen4d_elastogen RANKS 1 2 4)

# Small twin of the convergence validation driver (full run: see drivers/validation).
gen4d_driver_twin(validate_convergence_quick validate_convergence "1;2"
                  ARGS --steps 8 --voxel 0.05 --plain-cap 400)
