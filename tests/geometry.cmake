# Geometry: primitives, mesh readers, winding numbers, OpenVDB level sets, voxelization.
gen4d_test(geometry
  SOURCES test_geometry_shapes.cpp test_geometry_mesh.cpp test_geometry_vdb.cpp
  LIBS gen4d_geometry
  RANKS 1)
