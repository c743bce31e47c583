#include "core/Device.hpp"

#include <fmt/format.h>

#include <cstdlib>
#include <cstring>
#include <mutex>

#include "core/Log.hpp"

#if defined(GEN4D_CUDA)
#include <cuda_runtime_api.h>
#endif

namespace gen4d::exec {

namespace {

struct Selection {
  bool device = false;
  std::string description;
};

int local_rank() {
  for (const char* name : {"OMPI_COMM_WORLD_LOCAL_RANK", "SLURM_LOCALID", "MPI_LOCALRANKID"}) {
    const char* v = std::getenv(name);
    if (v && *v) return std::max(0, std::atoi(v));
  }
  return 0;
}

Selection select() {
  Selection s;
#if defined(GEN4D_CUDA)
  const char* choice = std::getenv("GEN4D_DEVICE");
  if (choice && std::strcmp(choice, "cpu") == 0) {
    s.description = "GPU not used (GEN4D_DEVICE=cpu)";
    return s;
  }
  int count = 0;
  const cudaError_t err = cudaGetDeviceCount(&count);
  if (err != cudaSuccess || count == 0) {
    s.description = fmt::format("no usable CUDA device ({}); kernels run on the CPU",
                                err != cudaSuccess ? cudaGetErrorString(err) : "none found");
    cudaGetLastError();  // clear the sticky error of a missing driver
    return s;
  }
  const int device = local_rank() % count;
  cudaDeviceProp prop{};
  if (cudaSetDevice(device) != cudaSuccess ||
      cudaGetDeviceProperties(&prop, device) != cudaSuccess) {
    s.description =
        fmt::format("CUDA device {} could not be selected; kernels run on the CPU", device);
    cudaGetLastError();
    return s;
  }
  s.device = true;
  s.description = fmt::format("{} (device {} of {}, sm_{}{})", prop.name, device, count, prop.major,
                              prop.minor);
#else
  s.description = "built without CUDA (GEN4D_CUDA=OFF); kernels run on the CPU";
#endif
  return s;
}

const Selection& selection() {
  static std::once_flag once;
  static Selection s;
  std::call_once(once, [] {
    s = select();
#if defined(GEN4D_CUDA)
    if (!s.device) log::warn_str(s.description);
#endif
  });
  return s;
}

}  // namespace

bool cuda_built() {
#if defined(GEN4D_CUDA)
  return true;
#else
  return false;
#endif
}

bool use_device() {
  return selection().device;
}

std::string device_description() {
  return selection().description;
}

}  // namespace gen4d::exec
