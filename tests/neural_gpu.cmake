# The CUDA half of the fused NeuralMTL kernel against the CPU kernel (skips without a GPU).
gen4d_test(neural_gpu SOURCES test_neural_gpu.cpp LIBS gen4d_neural RANKS 1 LABELS gpu)
