//! A rank's share of a splat set: the contiguous block [n r / p, n (r + 1) / p) of the splats,
//! what `gen4d render` and the ablation table draw on each rank.
#pragma once

#include <mpi.h>

#include <array>
#include <cstddef>

#include "gaussians/Splats.hpp"

namespace gen4d::driver {

//! This rank's block of `n` items: [n r / p, n (r + 1) / p).
inline std::array<std::size_t, 2> rank_block(MPI_Comm comm, std::size_t n) {
  int r = 0, p = 1;
  MPI_Comm_rank(comm, &r);
  MPI_Comm_size(comm, &p);
  return {n * r / p, n * (r + 1) / p};
}

//! Splats [lo, hi) of `s`.
inline gaussians::SplatSet block(const gaussians::SplatSet& s, std::size_t lo, std::size_t hi) {
  gaussians::SplatSet b;
  b.sh_degree = s.sh_degree;
  const std::size_t k = 3 * static_cast<std::size_t>(s.coefficients());
  b.position.assign(s.position.begin() + 3 * lo, s.position.begin() + 3 * hi);
  b.scale.assign(s.scale.begin() + 3 * lo, s.scale.begin() + 3 * hi);
  b.rotation.assign(s.rotation.begin() + 4 * lo, s.rotation.begin() + 4 * hi);
  b.opacity.assign(s.opacity.begin() + lo, s.opacity.begin() + hi);
  b.sh.assign(s.sh.begin() + k * lo, s.sh.begin() + k * hi);
  return b;
}

//! This rank's block of `s`.
inline gaussians::SplatSet rank_share(MPI_Comm comm, const gaussians::SplatSet& s) {
  const auto [lo, hi] = rank_block(comm, s.size());
  return block(s, lo, hi);
}

}  // namespace gen4d::driver
