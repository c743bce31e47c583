//! The CUDA half of the fused NeuralMTL kernel: NeuralPointKernel (NeuralMtlKernel.hpp, the
//! pass the CPU kernel runs) over the points, one point per thread.
#include <cuda_runtime_api.h>

#include <algorithm>
#include <mutex>
#include <vector>

#include "core/DeviceArray.hpp"
#include "core/ParallelFor.hpp"
#include "neural/NeuralMtl.hpp"

namespace gen4d::neural {

//! The network's padded weights in device memory and a NetView pointing into them.
struct NeuralMtl::DeviceCache {
  exec::DeviceArray<double> params;
  NetView view;
};

void NeuralMtl::evaluate_device(std::size_t n, const double* sigma, double* psi,
                                double* dpsi) const {
  {
    static std::mutex upload;
    std::lock_guard<std::mutex> lock(upload);
    if (!device_) {
      auto cache = std::make_shared<DeviceCache>();
      std::vector<double> flat;
      std::size_t offset[kMaxLayers][3];
      for (int l = 0; l < view_.layers; ++l) {
        const std::vector<double>* parts[3] = {&W_[l], &Wt_[l], &b_[l]};
        for (int k = 0; k < 3; ++k) {
          offset[l][k] = flat.size();
          flat.insert(flat.end(), parts[k]->begin(), parts[k]->end());
        }
      }
      cache->params.upload(flat.data(), flat.size());
      cache->view = view_;
      const double* base = cache->params.data();
      for (int l = 0; l < view_.layers; ++l) {
        cache->view.W[l] = base + offset[l][0];
        cache->view.Wt[l] = base + offset[l][1];
        cache->view.b[l] = base + offset[l][2];
      }
      device_ = std::move(cache);
    }
  }
  const NetView& view = device_->view;
  int widest = 0;
  for (int l = 0; l <= view.layers; ++l) widest = std::max(widest, view.width[l]);
  if (widest <= 32)
    exec::device_for(static_cast<long>(n),
                     NeuralPointKernel<true, 32>{view, sigma, psi, dpsi, nullptr});
  else
    exec::device_for(static_cast<long>(n),
                     NeuralPointKernel<true, kMaxWidth>{view, sigma, psi, dpsi, nullptr});
  exec::cuda_check(cudaGetLastError(), "NeuralMTL kernel launch");
  exec::cuda_check(cudaStreamSynchronize(nullptr), "NeuralMTL kernel");
}

}  // namespace gen4d::neural
