//! Parallel writer of one HDF5 file holding every frame of a run, with a ParaView XDMF index.
#pragma once

#include <mpi.h>

#include <cstdint>
#include <string>
#include <vector>

#include "io/FrameLayout.hpp"
#include "io/FramesFile.hpp"
#include "io/GridBox.hpp"
#include "io/Hdf5.hpp"

namespace gen4d::io {

//! Writes the occupancy once and one group per frame under kFramesGroup (position, velocity;
//! attributes time, step) per frame, collectively on `comm`. Datasets are global C-order arrays
//! [nz][ny][nx](3), so every decomposition writes the same file. After each frame the file is
//! flushed and rank 0 replaces the .xdmf index next to it, so an unfinished run is always viewable.
//! Every method is collective: ranks owning nothing pass an empty box.
class FrameWriter {
 public:
  //! Creates (truncates) `h5_path`. Throws RuntimeError when it cannot be written.
  FrameWriter(MPI_Comm comm, const std::string& h5_path, const GridMeta& meta);
  //! Reopens an existing frames file for a restarted run, keeping frames with step <=
  //! `keep_up_to_step` and deleting later ones. InputError when it is not a frames file.
  static FrameWriter open_append(MPI_Comm comm, const std::string& h5_path, int keep_up_to_step);

  FrameWriter(FrameWriter&&) = default;
  FrameWriter& operator=(FrameWriter&&) = default;
  ~FrameWriter() = default;

  //! Writes the cell occupancy (1 = solid) of this rank's cell box.
  void write_occupancy(const CellBox& cells, const std::uint8_t* occupancy);
  //! Appends a frame from this rank's node box: 3 interleaved doubles per node for the
  //! deformed positions `x` and velocities `v`.
  void write_frame(double time, int step, const NodeBox& nodes, const double* x, const double* v);
  //! Closes the file, reporting a failure to finish writing it (RuntimeError).
  void close();

  const std::vector<FrameInfo>& frames() const { return frames_; }
  const GridMeta& meta() const { return meta_; }
  const std::string& path() const { return file_.path(); }
  const std::string& xdmf_path() const { return file_.xdmf_path(); }

 private:
  FrameWriter(FramesFile file, GridMeta meta);
  void commit();

  FramesFile file_;
  GridMeta meta_;
  std::vector<FrameInfo> frames_;
  bool has_occupancy_ = false;
};

}  // namespace gen4d::io
