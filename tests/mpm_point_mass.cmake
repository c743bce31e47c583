# [[point_mass]] on MPM particles: where the mass lands (bit for bit at any rank count), free
# fall unchanged, an impulse moving the total mass, in the solver and diagnose's MPM model.
gen4d_test(mpm_point_mass SOURCES test_mpm_point_mass.cpp LIBS gen4d_mpm gen4d_forward
           RANKS 1 2 4)
