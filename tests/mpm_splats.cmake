# Splats as MPM particles: seeding, kinematics, bit-identity at 1, 2 and 4 ranks, restart.
gen4d_test(mpm_splats SOURCES test_mpm_splats.cpp LIBS gen4d_mpm RANKS 1 2 4)
