# gen4d diagnose: forward model, effects at their null values, noise estimator, rank-spread
# forward runs and TAO calibration (1 and 2 ranks).
# The end-to-end diagnoses run at 2 ranks only; DiagnoseAcrossRanks runs one at both and the
# 2-rank run compares its report with the 1-rank one's (so it needs diagnose_np1 first).
gen4d_test(diagnose SOURCES test_diagnose.cpp LIBS gen4d_diagnose RANKS 1 2
           LARGEST_RANKS_ONLY DiagnoseEndToEnd.*)
set_tests_properties(diagnose_np1 PROPERTIES FIXTURES_SETUP diagnose_one_rank_report)
set_tests_properties(diagnose_np2 PROPERTIES FIXTURES_REQUIRED diagnose_one_rank_report)
# Its reference sums for the vector kernels round every product and sum, like the kernels.
set_source_files_properties(test_diagnose.cpp PROPERTIES COMPILE_OPTIONS -ffp-contract=off)
# The diagnosis's stages (Pipeline.hpp) one at a time on a tiny cantilever (the ranks'
# agreement is DiagnoseAcrossRanks's).
gen4d_test(diagnose_stages SOURCES test_diagnose_stages.cpp LIBS gen4d_diagnose RANKS 1)
# The forward model's block LDL^T solver against Eigen's.
gen4d_test(block_ldlt SOURCES test_block_ldlt.cpp LIBS gen4d_diagnose RANKS 1)
# The forward model's von Mises return map against the MPM von_mises material.
gen4d_test(hencky_j2 SOURCES test_hencky_j2.cpp LIBS gen4d_diagnose RANKS 1)
# gen4d diagnose on MPM decks: the MPM solver as the forward model, and one diagnosis.
# Its end-to-end diagnoses run at 2 ranks only (the MPM model's runs are the same bit for bit
# at any rank count: DiagnoseMpmModel.RanksShareRunsBitForBit).
gen4d_test(diagnose_mpm SOURCES test_diagnose_mpm.cpp LIBS gen4d_diagnose RANKS 1 2
           LARGEST_RANKS_ONLY DiagnoseMpmEndToEnd.*)
# An effect defined in the test (one file) added to the library, recorded and diagnosed.
gen4d_test(diagnose_toy_effect SOURCES test_diagnose_toy_effect.cpp LIBS gen4d_diagnose RANKS 1)
