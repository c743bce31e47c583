//! What every frames file shares, grid or particles: one HDF5 file written collectively, one
//! group per frame under kFramesGroup, flushed after each frame, and an XDMF index beside it
//! that rank 0 replaces, so ParaView opens an unfinished run. The writers (io::FrameWriter,
//! mpm::ParticleFrameWriter) add their datasets and their index text.
#pragma once

#include <mpi.h>

#include <functional>
#include <string>

#include "io/Hdf5.hpp"

namespace gen4d::io {

class FramesFile {
 public:
  FramesFile() = default;
  //! Creates (truncates) `h5_path`, lets `fill_root` write the root attributes and creates
  //! kFramesGroup. RuntimeError on every rank when any rank fails.
  static FramesFile create(MPI_Comm comm, const std::string& h5_path,
                           const std::function<void(hid_t)>& fill_root);
  //! Wraps an already opened file (a restarted run appending to it).
  FramesFile(MPI_Comm comm, const std::string& h5_path, h5::Handle file);

  //! Throws RuntimeError on every rank when `local_error` is set on any.
  void raise_if_any(const std::string& local_error) const;
  //! Writes group `group_name` through fill(group), collectively. On a failure on any rank the
  //! partial group is removed (the file keeps only complete frames) and every rank throws
  //! RuntimeError prefixed by `where`.
  void write_group(const std::string& group_name, const std::string& where,
                   const std::function<void(hid_t)>& fill);
  //! Deletes group `group_name` (collective).
  void remove_group(const std::string& group_name);
  //! Flushes the file, then rank 0 replaces the index by index_text(the h5 file's name).
  void commit(const std::function<std::string(const std::string&)>& index_text);
  //! Closes the file, reporting a failure to finish writing it (RuntimeError).
  void close();

  hid_t get() const { return file_.get(); }
  MPI_Comm comm() const { return comm_; }
  int rank() const { return rank_; }
  const std::string& path() const { return path_; }
  const std::string& xdmf_path() const { return xdmf_path_; }

 private:
  MPI_Comm comm_ = MPI_COMM_NULL;
  int rank_ = 0;
  std::string path_;
  std::string xdmf_path_;
  h5::Handle file_;
};

}  // namespace gen4d::io
