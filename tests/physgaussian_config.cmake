# PhysGaussian JSON configs: reading, preprocessing and conversion to gen4d decks.
gen4d_test(physgaussian_config SOURCES test_physgaussian_config.cpp
           LIBS gen4d_gaussians gen4d_core RANKS 1)
