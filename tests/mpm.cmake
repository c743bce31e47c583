# MPM solver: bit-identity at 1, 2 and 4 ranks, conservation, boundary conditions, guard.
gen4d_test(mpm SOURCES test_mpm.cpp LIBS gen4d_mpm RANKS 1 2 4)
