# 3D Gaussian splats: 3DGS PLY reading and writing, kinematics, deck splat objects, occupancy.
gen4d_test(gaussians SOURCES test_gaussians.cpp LIBS gen4d_gaussians RANKS 1)
