gen4d_test(parallel SOURCES test_parallel.cpp LIBS gen4d_parallel RANKS 1 2 4)
