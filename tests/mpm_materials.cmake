# MPM constitutive models with return maps and their registry (serial).
gen4d_test(mpm_materials SOURCES test_mpm_materials.cpp LIBS gen4d_mpm RANKS 1)
