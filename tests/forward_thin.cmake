# The voxel forward model on box cells (a thin strip vs Euler-Bernoulli), attached masses and
# pre-loads.
gen4d_test(forward_thin SOURCES test_forward_thin.cpp LIBS gen4d_forward RANKS 1)
