gen4d_test(elastogen SOURCES test_elastogen.cpp LIBS gen4d_elastogen RANKS 1 2 4)
gen4d_test(cantilever SOURCES test_cantilever.cpp LIBS gen4d_elastogen RANKS 1)
gen4d_test(stencil SOURCES test_stencil.cpp LIBS gen4d_elastogen RANKS 1)
