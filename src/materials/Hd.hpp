//! GEN4D_HD marks pointwise functions that nvcc must compile for both host and device.
#pragma once

#if defined(__CUDACC__)
#define GEN4D_HD __host__ __device__
#else
#define GEN4D_HD
#endif
