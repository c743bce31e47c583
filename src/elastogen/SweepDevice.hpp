//! The global step's damped-Jacobi sweep on this rank's GPU (CUDA build only): the same
//! JacobiSweepKernel as the host's reference path, one thread per degree of freedom.
#pragma once

#if defined(GEN4D_CUDA)
#include <cstddef>
#include <memory>

#include "elastogen/SweepKernel.hpp"

namespace gen4d::elastogen {

//! Keeps the operator's node arrays (diagonal, masses, masks) and two iterates on the device.
//! Sweeps run back to back on the device with the ghost values held at what was uploaded:
//! a single-rank solve, or one sweep between halo exchanges done by the caller.
class DeviceJacobi {
 public:
  //! `host`: VoxelSystem::jacobi_kernel with host pointers (its diag, mass, free and adj
  //! arrays are uploaded; r, d_old, d_new and res are ignored); `nodes`: ghosted nodes.
  DeviceJacobi(const JacobiSweepKernel& host, std::size_t nodes);
  ~DeviceJacobi();
  DeviceJacobi(const DeviceJacobi&) = delete;
  DeviceJacobi& operator=(const DeviceJacobi&) = delete;

  //! Uploads the right-hand side r and the iterate d (3 values per ghosted node).
  void set(const double* r, const double* d);
  //! `sweeps` sweeps (the residual r - A d_old stored on the last); returns the device time in
  //! seconds, measured with CUDA events around the launches.
  double sweep(int sweeps);
  //! Downloads the iterate and the last sweep's residual (3 values per ghosted node; only
  //! owned values are written by the sweeps, the others are as uploaded / zero).
  void get(double* d, double* res) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

//! The current device's nominal memory bandwidth (bytes/s): 2 x memory clock x bus width.
double device_memory_bandwidth();
//! STREAM triad a = b + s c on the current device over n doubles per array, best of 5
//! (bytes/s, 24 bytes per element).
double device_stream_triad(std::size_t n);

}  // namespace gen4d::elastogen
#endif
