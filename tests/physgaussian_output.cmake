# PhysGaussian's output layout: gs_simulation.py's image names, [render] scenery drawn bit for bit
# at 1, 2 and 4 ranks, and the --output_ply particle files.
gen4d_test(physgaussian_output SOURCES test_physgaussian_output.cpp LIBS gen4d_gaussians
           RANKS 1 2 4)
