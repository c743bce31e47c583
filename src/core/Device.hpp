//! The GPU of this rank, in a build with the CUDA back end (GEN4D_CUDA=ON).
//
// One GPU per rank, chosen by the node-local rank (OMPI_COMM_WORLD_LOCAL_RANK, SLURM_LOCALID)
// modulo the node's devices. A rank without a usable device (none installed, no driver, or
// GEN4D_DEVICE=cpu) says so once and its kernels run on the host; the results are the same
// either way up to the tolerances the GPU tests state.
#pragma once

#include <string>

namespace gen4d::exec {

//! Whether this binary was built with the CUDA back end.
bool cuda_built();
//! Whether this rank runs its kernels on a GPU. The first call selects the device (and logs
//! once why there is none); later calls are free.
bool use_device();
//! "NVIDIA H100 80GB HBM3 (device 0 of 1, sm_90)", or why there is no device.
std::string device_description();

}  // namespace gen4d::exec
