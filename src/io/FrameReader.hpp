//! Serial reader of a gen4d frames file, for previews, tests and post-processing.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "io/FrameLayout.hpp"
#include "io/Hdf5.hpp"

namespace gen4d::io {

//! Opens a frames file on one process (any rank count wrote it) and reads whole global arrays,
//! C-order [nz][ny][nx] (x fastest) with 3 interleaved components for vectors.
//! Every failure is an InputError naming the file and, where known, the dataset.
class FrameReader {
 public:
  explicit FrameReader(const std::string& h5_path);

  const std::string& path() const { return path_; }
  const GridMeta& meta() const { return meta_; }
  const std::array<long, 3>& node_dims() const { return meta_.node_dims; }
  const std::map<std::string, std::string>& attributes() const { return meta_.attributes; }
  const std::vector<FrameInfo>& frames() const { return frames_; }
  int frame_count() const { return static_cast<int>(frames_.size()); }

  //! Node positions of frame `n` (0-based position in frames()).
  std::vector<double> read_position(int n) const;
  std::vector<double> read_velocity(int n) const;
  //! Cell occupancy, [nz-1][ny-1][nx-1]; 1 marks a solid voxel.
  std::vector<std::uint8_t> read_occupancy() const;

 private:
  std::vector<double> read_vectors(int n, const char* name) const;

  std::string path_;
  h5::Handle file_;
  GridMeta meta_;
  std::vector<FrameInfo> frames_;
};

}  // namespace gen4d::io
