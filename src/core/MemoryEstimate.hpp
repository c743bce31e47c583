//! A run's memory, estimated from its deck before anything is allocated, and the check that
//! refuses a run the machine cannot hold (gen4d run/restart; --skip-memory-check skips it).
#pragma once

#include <mpi.h>

#include <string>

#include "core/Config.hpp"

namespace gen4d::memory {

//! Bytes per item, fitted to the peak resident memory (GNU time's maxrss) of 1-rank runs with
//! OMP_NUM_THREADS=1, 2 steps each:
//!   ElastoGen, inputs/jelly_board.toml at domain.voxel_size 0.02 / 0.01 / 0.007 / 0.005 m:
//!     1740 / 13888 / 39956 / 111028 solid voxels (43x11x12 ... 163x35x39 nodes): 232 / 259 /
//!     315 / 450 MB; about 2 kB per voxel with its share of nodes.
//!   MPM, inputs/mpm_sand.toml at 0.01 / 0.005 / 0.0035 m: 20000 / 160000 / 461358 particles,
//!     110000 / 880000 / 2598410 cells: 285 / 624 / 1307 MB; at 0.005 m with 4725000 cells
//!     (mpm.hi = [1, 0.5, 0.7]): 1269 MB, which separates cells (172 B) from particles (1530 B).
//!   A rank's fixed part (MPI, PETSc, HDF5, the executable) is about 230-240 MB.
//! The estimate (with one rank's fixed part) of the largest runs above is 3-9 % above the
//! measurement: 489 MB for 450 (ElastoGen at 0.005 m), 1405 MB for 1307 (MPM at 0.0035 m).
inline constexpr double kElastoGenBytesPerVoxel = 1800;
inline constexpr double kElastoGenBytesPerNode = 100;
inline constexpr double kMpmBytesPerParticle = 1530;
inline constexpr double kMpmBytesPerCell = 172;
inline constexpr double kBytesPerRank = 240.0 * (1 << 20);

struct Estimate {
  //! False when the size depends on a file (mesh, vdb, splats parts): no estimate then.
  bool known = false;
  double items = 0;       //!< ElastoGen: solid voxels; MPM: particles
  double grid = 0;        //!< ElastoGen: grid nodes; MPM: grid cells
  double bytes = 0;       //!< items and grid, every rank together (kBytesPerRank not included)
  std::string breakdown;  //!< "N solid voxels x B bytes + M grid nodes x C bytes"
};

//! The estimate of `cfg` (its solver, domain.voxel_size and analytic [[geometry]] parts).
Estimate estimate(const Config& cfg);

//! MemAvailable of /proc/meminfo in bytes (free pages x page size without it); -1 if unknown.
double available_bytes();

//! "37.2 GiB"
std::string format_bytes(double bytes);

//! Collective: throws RuntimeError on every rank when the ranks on some node of `comm` need
//! more than that node's available memory, with the estimate, what the node has and what to
//! change. Nothing happens when the estimate is not known.
void check(MPI_Comm comm, const Config& cfg);

}  // namespace gen4d::memory
