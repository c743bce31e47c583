//! GEN4D_HD marks pointwise functions that nvcc must compile for both host and device.
#pragma once

#if defined(__CUDACC__)
#define GEN4D_HD __host__ __device__
#else
#define GEN4D_HD
#endif

//! Asks the host compiler to vectorise the loop that follows (OpenMP simd); nothing on a device.
#if defined(_OPENMP) && !defined(__CUDA_ARCH__)
#define GEN4D_SIMD _Pragma("omp simd")
#else
#define GEN4D_SIMD
#endif
