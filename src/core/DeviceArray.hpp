//! Device memory for the CUDA back end: an owning array and the error check every CUDA call
//! goes through. Included only where GEN4D_CUDA is defined (the .cu files and their hosts).
#pragma once

#if defined(GEN4D_CUDA)
#include <cuda_runtime_api.h>
#include <fmt/format.h>

#include <cstddef>
#include <utility>

#include "core/Error.hpp"

namespace gen4d::exec {

//! Throws RuntimeError "CUDA: WHAT: <error string>" unless `err` is cudaSuccess.
inline void cuda_check(cudaError_t err, const char* what) {
  if (err != cudaSuccess) {
    cudaGetLastError();
    throw RuntimeError(fmt::format("CUDA: {}: {}", what, cudaGetErrorString(err)));
  }
}

//! n elements of T in device memory; grows on demand (never shrinks), moves, no copies.
template <class T>
class DeviceArray {
 public:
  DeviceArray() = default;
  explicit DeviceArray(std::size_t n) { resize(n); }
  DeviceArray(const DeviceArray&) = delete;
  DeviceArray& operator=(const DeviceArray&) = delete;
  DeviceArray(DeviceArray&& o) noexcept { swap(o); }
  DeviceArray& operator=(DeviceArray&& o) noexcept {
    swap(o);
    return *this;
  }
  ~DeviceArray() {
    if (p_) cudaFree(p_);
  }
  void swap(DeviceArray& o) noexcept {
    std::swap(p_, o.p_);
    std::swap(n_, o.n_);
    std::swap(cap_, o.cap_);
  }
  //! Size n; the contents are kept only when no reallocation happens.
  void resize(std::size_t n) {
    if (n > cap_) {
      if (p_) cudaFree(p_);
      p_ = nullptr;
      cuda_check(cudaMalloc(reinterpret_cast<void**>(&p_), n * sizeof(T)), "cudaMalloc");
      cap_ = n;
    }
    n_ = n;
  }
  void upload(const T* host, std::size_t n) {
    resize(n);
    if (n) cuda_check(cudaMemcpy(p_, host, n * sizeof(T), cudaMemcpyHostToDevice), "upload");
  }
  void download(T* host, std::size_t n) const {
    if (n) cuda_check(cudaMemcpy(host, p_, n * sizeof(T), cudaMemcpyDeviceToHost), "download");
  }
  void zero() {
    if (n_) cuda_check(cudaMemset(p_, 0, n_ * sizeof(T)), "cudaMemset");
  }
  T* data() { return p_; }
  const T* data() const { return p_; }
  std::size_t size() const { return n_; }

 private:
  T* p_ = nullptr;
  std::size_t n_ = 0, cap_ = 0;
};

}  // namespace gen4d::exec
#endif
