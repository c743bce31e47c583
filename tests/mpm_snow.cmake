# MPM snow (Stomakhin et al. 2013): return map, hardening, and a dropped block at 1 and 2 ranks.
gen4d_test(mpm_snow SOURCES test_mpm_snow.cpp LIBS gen4d_mpm RANKS 1 2)
