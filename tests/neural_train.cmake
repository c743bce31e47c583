# LibTorch half of NeuralMTL (serial): torch laws vs the C++ materials, a tiny fit, the fused
# kernel vs LibTorch, the AE + DDPM round trip and the generator's file checks.
if(GEN4D_HAVE_TORCH)
  gen4d_test(neural_train SOURCES test_neural_train.cpp LIBS gen4d_neural_train RANKS 1)
endif()
if(GEN4D_HAVE_TORCH AND TARGET gen4d)
  add_test(NAME cli_neural
           COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/cli_neural.sh $<TARGET_FILE:gen4d>
                   ${CMAKE_CURRENT_BINARY_DIR}/scratch/cli_neural
                   ${CMAKE_SOURCE_DIR}/inputs/models/generator.h5)
  set_tests_properties(cli_neural PROPERTIES ENVIRONMENT "${GEN4D_TEST_ENV}" TIMEOUT 300)
endif()
