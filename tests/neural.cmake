# NeuralMTL without LibTorch: fused kernel, activation properties, weight files (serial).
gen4d_test(neural SOURCES test_neural.cpp LIBS gen4d_neural RANKS 1)
