# PhysGaussian's boundary conditions and damping in the MPM solver: moving cuboid and reset,
# the "cut" collider, RPIC / PIC, grid velocity damping, their deck keys; 1 and 2 ranks agree.
gen4d_test(mpm_boundaries SOURCES test_mpm_boundaries.cpp LIBS gen4d_mpm RANKS 1 2)
