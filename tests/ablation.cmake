# The seed's ablation table (drivers/validation/AblationTable.hpp): the deformation maps' gradients,
# the subdivided truth (moments, opacity rule, convergence) and, on small synthetic SH-3 objects,
# the full kinematics beating each ablation; the same numbers at 1 and 2 ranks.
gen4d_test(ablation SOURCES test_ablation.cpp LIBS gen4d_gaussians RANKS 1 2)
target_include_directories(test_ablation PRIVATE ${CMAKE_SOURCE_DIR}/drivers)
