# MPM solver: bit-identity at 1, 2 and 4 ranks, conservation, boundary conditions, guard.
gen4d_test(mpm SOURCES test_mpm.cpp LIBS gen4d_mpm RANKS 1 2 4)
# The host kernels on 1, 2 and 3 threads (bit-identical), svd3_batch against svd3.
gen4d_test(mpm_threads SOURCES test_mpm_threads.cpp LIBS gen4d_mpm RANKS 1 2)
# The kernels on a GPU against the host (skips without a CUDA device).
gen4d_test(mpm_gpu SOURCES test_mpm_gpu.cpp LIBS gen4d_mpm RANKS 1 2 LABELS gpu)
