//! Decomposition-independent restart files: global node arrays plus the run's clock and deck.
#pragma once

#include <mpi.h>

#include <array>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "io/BytePack.hpp"
#include "io/GridBox.hpp"
#include "io/Hdf5.hpp"

namespace gen4d::io {

inline constexpr const char* kCheckpointFormat = "gen4d-checkpoint";
inline constexpr long kCheckpointFormatVersion = 1;

//! The run's clock and deck, which every checkpoint (grid or particles) stores alike.
struct RunClock {
  int step = 0;
  double time = 0;
  int frame_index = 0;         //!< index of the next frame to write
  double next_frame_time = 0;  //!< simulated time of the next frame
  std::string deck_text;
  std::map<std::string, double> extras;  //!< solver scalars a restart must restore
};

//! What a rank hands to write_checkpoint: the run's clock, its deck, and its owned node box of
//! positions and velocities (3 interleaved doubles per node, x-fastest over the box).
struct CheckpointState : RunClock {
  std::array<long, 3> node_dims{0, 0, 0};
  NodeBox owned;
  const double* x = nullptr;
  const double* v = nullptr;
};

//! Everything in a checkpoint except the node arrays.
struct CheckpointMeta : RunClock {
  std::array<long, 3> node_dims{0, 0, 0};
};

// ---- the parts every checkpoint format shares ----------------------------------------------

//! The clock as root attributes (step, time, frame_index, next_frame_time, deck) and the
//! /extras group.
void write_run_clock(hid_t file, const RunClock& clock);
//! Reads what write_run_clock wrote; InputError naming `path` for a missing or bad entry.
RunClock read_run_clock(hid_t file, const std::string& path);
//! Byte packing of the clock for a broadcast from the rank that read it.
void pack_run_clock(std::string& buffer, const RunClock& clock);
void unpack_run_clock(bytes::Unpacker& in, RunClock& clock);

//! First step of writing a checkpoint: throws RuntimeError on every rank when any rank has a
//! `local_error`, or when rank 0 cannot create `dir`.
void prepare_checkpoint_dir(MPI_Comm comm, const std::string& dir, const std::string& local_error);
//! Second step: writes checkpoint_path(dir, step) collectively as a hidden temporary filled by
//! fill(file) on every rank; rank 0 renames it and deletes all but the newest `keep`
//! checkpoints (keep <= 0 keeps all). Returns the path on every rank once it exists. On failure
//! nothing is left under the final name and every rank throws RuntimeError.
std::string commit_checkpoint_file(MPI_Comm comm, const std::string& dir, int step, int keep,
                                   const std::function<void(hid_t)>& fill);

//! dir/checkpoint_<step, 8 digits>.h5
std::string checkpoint_path(const std::string& dir, int step);

//! Writes the checkpoint of `state.step` collectively to a hidden temporary in `dir`, then
//! rank 0 renames it to checkpoint_path(dir, step) and deletes all but the newest `keep`
//! checkpoints (keep <= 0 keeps all). Returns the path on every rank once it exists.
//! On failure nothing is left under the final name and every rank throws RuntimeError.
std::string write_checkpoint(MPI_Comm comm, const std::string& dir, const CheckpointState& state,
                             int keep);

//! First phase of a restart: the metadata, read on rank 0 and shared, so the caller can
//! decompose the grid. Throws InputError (on every rank) naming the file and the problem.
CheckpointMeta read_checkpoint_meta(MPI_Comm comm, const std::string& path);

//! Second phase: reads this rank's `owned` node box (any decomposition) collectively.
//! Throws InputError on every rank naming the file and the problem.
void read_checkpoint_fields(MPI_Comm comm, const std::string& path, const NodeBox& owned,
                            std::vector<double>& x, std::vector<double>& v);

//! Both phases, when the caller already knows its box.
CheckpointMeta read_checkpoint(MPI_Comm comm, const std::string& path, const NodeBox& owned,
                               std::vector<double>& x, std::vector<double>& v);

//! Path of the checkpoint with the highest step in `dir`; "" when there is none.
std::string latest_checkpoint(const std::string& dir);

//! Deletes all but the newest `keep` checkpoint_<digits>.h5 files in `dir` (keep <= 0 keeps
//! all). A file that cannot be removed is logged as a warning, not thrown.
void prune_checkpoints(const std::string& dir, int keep);

}  // namespace gen4d::io
