# Finds every dependency of gen4d (Debian packages only; see cmake/install-deps.sh)
# and exposes them as imported targets.
find_package(PkgConfig REQUIRED)
find_package(MPI REQUIRED COMPONENTS C CXX)
find_package(Threads REQUIRED)
# Host threads of the pointwise kernels (core/ParallelFor.hpp).
find_package(OpenMP REQUIRED COMPONENTS CXX)

pkg_check_modules(PETSC REQUIRED IMPORTED_TARGET PETSc)
pkg_check_modules(HDF5MPI REQUIRED IMPORTED_TARGET hdf5-openmpi)

find_package(Eigen3 3.3 REQUIRED NO_MODULE)
find_package(tomlplusplus REQUIRED)
find_package(CLI11 REQUIRED)
find_package(fmt REQUIRED)
find_package(spdlog REQUIRED)
find_package(PNG REQUIRED)
find_package(GTest REQUIRED)

# OpenVDB ships only a find module.
list(APPEND CMAKE_MODULE_PATH /usr/lib/x86_64-linux-gnu/cmake/OpenVDB /usr/lib/cmake/OpenVDB)
find_package(OpenVDB REQUIRED COMPONENTS openvdb)

set(GEN4D_HAVE_TORCH OFF)
if(GEN4D_TORCH)
  find_package(Torch QUIET)
  if(Torch_FOUND)
    set(GEN4D_HAVE_TORCH ON)
  else()
    message(WARNING "GEN4D_TORCH=ON but LibTorch was not found (apt install libtorch-dev); training tools disabled")
  endif()
endif()

set(GEN4D_PETSC_VERSION ${PETSC_VERSION})
set(GEN4D_HDF5_VERSION ${HDF5MPI_VERSION})
