# Internal filling of splat objects (PhysGaussian seed §3.7).
gen4d_test(filling SOURCES test_filling.cpp LIBS gen4d_gaussians RANKS 1)
