# Several materials in one deck: deck checks, slots, and bit-identity at 1, 2 and 4 ranks.
gen4d_test(multi_material SOURCES test_multi_material.cpp LIBS gen4d_mpm gen4d_elastogen RANKS 1 2 4)
