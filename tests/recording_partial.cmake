# Recordings that measure some values only (empty cells, column subsets, NaN, --unmeasured),
# their noise, sensors on the surface; the stages observe and calibrate on a partial and on a
# mid-motion recording run at 2 ranks only (the runs spread over the ranks).
gen4d_test(recording_partial SOURCES test_recording_partial.cpp LIBS gen4d_diagnose RANKS 1 2
           LARGEST_RANKS_ONLY PartialRecordingDiagnosis.*)
