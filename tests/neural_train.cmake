# LibTorch half of NeuralMTL (serial): torch laws vs the C++ materials, a tiny fit, the fused
# kernel vs LibTorch, the AE + DDPM round trip and the generator's file checks.
if(GEN4D_HAVE_TORCH)
  gen4d_test(neural_train SOURCES test_neural_train.cpp LIBS gen4d_neural_train RANKS 1)
endif()
