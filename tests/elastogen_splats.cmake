# 3D Gaussian splats carried by ElastoGen's voxels (embedding, rank independence, rendering).
gen4d_test(elastogen_splats SOURCES test_elastogen_splats.cpp LIBS gen4d_elastogen PNG::PNG
           RANKS 1 2 4)
