#include "io/FrameReader.hpp"

#include "core/Error.hpp"

namespace gen4d::io {

FrameReader::FrameReader(const std::string& h5_path)
    : path_(h5_path), file_(h5::open_file_serial(h5_path)) {
  meta_ = read_grid_meta(file_.get(), path_);
  frames_ = list_frames(file_.get(), path_);
}

std::vector<double> FrameReader::read_vectors(int n, const char* name) const {
  if (n < 0 || n >= frame_count()) {
    throw InputError(path_ + ": no frame " + std::to_string(n) + " (the file holds " +
                     std::to_string(frame_count()) + ")");
  }
  const std::string dataset_path = frame_group(frames_[n].index) + "/" + name;
  h5::Handle dataset =
      h5::open_grid_dataset(file_.get(), dataset_path, H5T_FLOAT, meta_.node_dims, 3, path_);
  const auto& d = meta_.node_dims;
  std::vector<double> values(3 * static_cast<std::size_t>(d[0] * d[1] * d[2]));
  h5::read_all(dataset.get(), H5T_NATIVE_DOUBLE, values.data(),
               path_ + ": cannot read dataset " + dataset_path);
  return values;
}

std::vector<double> FrameReader::read_position(int n) const {
  return read_vectors(n, "position");
}

std::vector<double> FrameReader::read_velocity(int n) const {
  return read_vectors(n, "velocity");
}

std::vector<std::uint8_t> FrameReader::read_occupancy() const {
  const std::array<long, 3> dims = cell_dims(meta_.node_dims);
  h5::Handle dataset =
      h5::open_grid_dataset(file_.get(), "/occupancy", H5T_INTEGER, dims, 1, path_);
  std::vector<std::uint8_t> values(static_cast<std::size_t>(dims[0] * dims[1] * dims[2]));
  h5::read_all(dataset.get(), H5T_NATIVE_UINT8, values.data(),
               path_ + ": cannot read dataset /occupancy");
  return values;
}

}  // namespace gen4d::io
