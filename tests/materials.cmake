# Pointwise materials: signed 3x3 SVD, constitutive models, registry (serial).
gen4d_test(svd3 SOURCES test_svd3.cpp LIBS gen4d_materials RANKS 1)
gen4d_test(materials SOURCES test_materials.cpp LIBS gen4d_materials RANKS 1)
# The one law vocabulary of every solver: names, old spellings, implementations (serial).
gen4d_test(materials_registry SOURCES test_materials_registry.cpp LIBS gen4d_mpm RANKS 1)
