# ElastoGen's pointwise kernels: factored Gauss-point stencil and Newton-polar stress against
# their references, the threaded sweep and local step bit-identical at 1, 2 and 3 threads.
gen4d_test(elastogen_kernels SOURCES test_elastogen_kernels.cpp LIBS gen4d_elastogen RANKS 1)
# The Jacobi sweep on a GPU against the host (skips without a CUDA device).
gen4d_test(elastogen_kernels_gpu SOURCES test_elastogen_kernels_gpu.cpp LIBS gen4d_elastogen
           RANKS 1 LABELS gpu)
