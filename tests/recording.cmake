# Tests of src/diagnose/Recording: marker and accelerometer recordings in CSV and HDF5, good and
# bad files.
gen4d_test(recording SOURCES test_recording.cpp LIBS gen4d_diagnose RANKS 1)
