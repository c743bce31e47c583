# gen4d diagnose: forward model, effects at their null values, noise estimator, rank-spread
# forward runs and TAO calibration (1 and 2 ranks).
gen4d_test(diagnose SOURCES test_diagnose.cpp LIBS gen4d_diagnose RANKS 1 2)
