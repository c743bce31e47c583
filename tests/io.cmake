# Tests of src/io: frames, checkpoints, bad files, PNG previews.
gen4d_test(io_frames SOURCES test_io_frames.cpp LIBS gen4d_io RANKS 1 2 4)
gen4d_test(io_checkpoint SOURCES test_io_checkpoint.cpp LIBS gen4d_io RANKS 1 2 4)
gen4d_test(io_bad_files SOURCES test_io_bad_files.cpp LIBS gen4d_io RANKS 1 2)
gen4d_test(io_png SOURCES test_io_png.cpp LIBS gen4d_io PNG::PNG RANKS 1)
