#include "io/FrameWriter.hpp"

#include <filesystem>

#include "core/Error.hpp"
#include "io/Xdmf.hpp"

namespace gen4d::io {
namespace {

//! Why this rank cannot write `box` of a grid with `dims`; "" when it can.
std::string box_problem(const NodeBox& box, const std::array<long, 3>& dims,
                        std::initializer_list<const void*> data) {
  if (!box.inside(dims)) return "box outside the grid";
  if (box.empty()) return "";
  for (const void* p : data) {
    if (p == nullptr) return "no data for a non-empty box";
  }
  return "";
}

}  // namespace

FrameWriter::FrameWriter(MPI_Comm comm, const std::string& h5_path, h5::Handle file, GridMeta meta)
    : comm_(comm),
      path_(h5_path),
      xdmf_path_(xdmf_path_for(h5_path)),
      file_(std::move(file)),
      meta_(std::move(meta)) {
  MPI_Comm_rank(comm_, &rank_);
}

FrameWriter::FrameWriter(MPI_Comm comm, const std::string& h5_path, const GridMeta& meta)
    : FrameWriter(comm, h5_path, h5::Handle(), meta) {
  for (long n : meta.node_dims) {
    if (n < 2) throw RuntimeError(h5_path + ": a frames grid needs at least 2 nodes per axis");
  }
  std::string error;
  try {
    file_ = h5::create_file(comm, h5_path);
    write_grid_meta(file_.get(), meta_);
    h5::create_group(file_.get(), kFramesGroup);
  } catch (const std::exception& e) {
    error = h5_path + ": " + e.what();
  }
  raise_if_any(error);
  flush();
  update_index();
}

FrameWriter FrameWriter::open_append(MPI_Comm comm, const std::string& h5_path,
                                     int keep_up_to_step) {
  h5::Handle file = h5::open_file(comm, h5_path, true);
  GridMeta meta = read_grid_meta(file.get(), h5_path);
  std::vector<FrameInfo> stored = list_frames(file.get(), h5_path);
  FrameWriter writer(comm, h5_path, std::move(file), std::move(meta));
  writer.has_occupancy_ = h5::link_exists(writer.file_.get(), "/occupancy");
  if (!h5::link_exists(writer.file_.get(), kFramesGroup)) {
    h5::create_group(writer.file_.get(), kFramesGroup);
  }
  for (const FrameInfo& frame : stored) {
    if (frame.step <= keep_up_to_step) {
      writer.frames_.push_back(frame);
    } else {
      // Unlinking is collective metadata work, identical on every rank.
      h5::check(H5Ldelete(writer.file_.get(), frame_group(frame.index).c_str(), H5P_DEFAULT),
                h5::Failure::Runtime, h5_path + ": cannot delete " + frame_group(frame.index));
    }
  }
  writer.flush();
  writer.update_index();
  return writer;
}

void FrameWriter::raise_if_any(const std::string& local_error) const {
  std::string error = h5::first_error(comm_, local_error);
  if (!error.empty()) throw RuntimeError(error);
}

void FrameWriter::flush() {
  h5::check(H5Fflush(file_.get(), H5F_SCOPE_GLOBAL), h5::Failure::Runtime,
            path_ + ": cannot flush");
}

void FrameWriter::update_index() {
  std::string error;
  if (rank_ == 0) {
    try {
      std::string h5_name = std::filesystem::path(path_).filename().string();
      write_text_atomically(xdmf_path_,
                            xdmf_text(h5_name, meta_.node_dims, frames_, has_occupancy_));
    } catch (const std::exception& e) {
      error = e.what();
    }
  }
  raise_if_any(error);
}

void FrameWriter::write_occupancy(const CellBox& cells, const std::uint8_t* occupancy) {
  const std::array<long, 3> dims = cell_dims(meta_.node_dims);
  std::string problem = box_problem(cells, dims, {occupancy});
  raise_if_any(problem.empty() ? "" : path_ + ": occupancy: " + problem);
  std::string error;
  try {
    h5::Handle dataset =
        has_occupancy_
            ? h5::open_grid_dataset(file_.get(), "/occupancy", H5T_INTEGER, dims, 1, path_)
            : h5::create_grid_dataset(file_.get(), "/occupancy", H5T_STD_U8LE, dims, 1);
    h5::write_box(dataset.get(), H5T_NATIVE_UINT8, cells, 1, occupancy);
  } catch (const std::exception& e) {
    error = path_ + ": occupancy: " + e.what();
  }
  raise_if_any(error);
  has_occupancy_ = true;
  flush();
  update_index();
}

void FrameWriter::write_frame(double time, int step, const NodeBox& nodes, const double* x,
                              const double* v) {
  const std::string where = path_ + ": frame at step " + std::to_string(step) + ": ";
  std::string problem = box_problem(nodes, meta_.node_dims, {x, v});
  raise_if_any(problem.empty() ? "" : where + problem);
  const int index = frames_.empty() ? 0 : frames_.back().index + 1;
  const std::string group_name = frame_group(index);
  std::string error;
  try {
    h5::Handle group = h5::create_group(file_.get(), group_name);
    h5::write_attr(group.get(), "time", time);
    h5::write_attr(group.get(), "step", static_cast<long>(step));
    h5::Handle position =
        h5::create_grid_dataset(group.get(), "position", H5T_IEEE_F64LE, meta_.node_dims, 3);
    h5::write_box(position.get(), H5T_NATIVE_DOUBLE, nodes, 3, x);
    h5::Handle velocity =
        h5::create_grid_dataset(group.get(), "velocity", H5T_IEEE_F64LE, meta_.node_dims, 3);
    h5::write_box(velocity.get(), H5T_NATIVE_DOUBLE, nodes, 3, v);
  } catch (const std::exception& e) {
    error = where + e.what();
  }
  error = h5::first_error(comm_, error);
  if (!error.empty()) {
    // Drop the partial group so the file holds only complete frames.
    if (h5::link_exists(file_.get(), group_name)) {
      H5Ldelete(file_.get(), group_name.c_str(), H5P_DEFAULT);
    }
    throw RuntimeError(error);
  }
  frames_.push_back({index, step, time});
  flush();
  update_index();
}

void FrameWriter::close() {
  file_.close(h5::Failure::Runtime, path_ + ": cannot close");
}

}  // namespace gen4d::io
