# Surface output: PLY/OBJ files and previews (io), the embedded surface and its sequence (elastogen).
gen4d_test(io_surface SOURCES test_io_surface.cpp LIBS gen4d_io PNG::PNG RANKS 1)
gen4d_test(surface SOURCES test_surface.cpp LIBS gen4d_elastogen RANKS 1 2 4)
gen4d_cli_test(cli_surface)
