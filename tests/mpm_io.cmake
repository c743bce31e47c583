# Tests of src/mpm/ParticleIO: checkpoints, frames, PLY, VDB and PNG output of the particles.
gen4d_test(mpm_io SOURCES test_mpm_io.cpp LIBS gen4d_mpm RANKS 1 2 4)
