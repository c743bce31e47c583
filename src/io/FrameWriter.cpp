#include "io/FrameWriter.hpp"

#include "core/Error.hpp"
#include "io/AtomicFile.hpp"
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

FrameWriter::FrameWriter(FramesFile file, GridMeta meta)
    : file_(std::move(file)), meta_(std::move(meta)) {}

FrameWriter::FrameWriter(MPI_Comm comm, const std::string& h5_path, const GridMeta& meta)
    : meta_(meta) {
  for (long n : meta.node_dims) {
    if (n < 2) throw RuntimeError(h5_path + ": a frames grid needs at least 2 nodes per axis");
  }
  file_ = FramesFile::create(comm, h5_path, [&](hid_t root) { write_grid_meta(root, meta_); });
  commit();
}

FrameWriter FrameWriter::open_append(MPI_Comm comm, const std::string& h5_path,
                                     int keep_up_to_step) {
  h5::Handle file = h5::open_file(comm, h5_path, true);
  GridMeta meta = read_grid_meta(file.get(), h5_path);
  std::vector<FrameInfo> stored = list_frames(file.get(), h5_path);
  FrameWriter writer(FramesFile(comm, h5_path, std::move(file)), std::move(meta));
  writer.has_occupancy_ = h5::link_exists(writer.file_.get(), "/occupancy");
  if (!h5::link_exists(writer.file_.get(), kFramesGroup)) {
    h5::create_group(writer.file_.get(), kFramesGroup);
  }
  for (const FrameInfo& frame : stored) {
    if (frame.step <= keep_up_to_step)
      writer.frames_.push_back(frame);
    else
      writer.file_.remove_group(frame_group(frame.index));
  }
  writer.commit();
  return writer;
}

void FrameWriter::commit() {
  file_.commit([&](const std::string& h5_name) {
    return xdmf_text(h5_name, meta_.node_dims, frames_, has_occupancy_);
  });
}

void FrameWriter::write_occupancy(const CellBox& cells, const std::uint8_t* occupancy) {
  const std::array<long, 3> dims = cell_dims(meta_.node_dims);
  std::string problem = box_problem(cells, dims, {occupancy});
  file_.raise_if_any(problem.empty() ? "" : path() + ": occupancy: " + problem);
  std::string error;
  try {
    h5::Handle dataset =
        has_occupancy_
            ? h5::open_grid_dataset(file_.get(), "/occupancy", H5T_INTEGER, dims, 1, path())
            : h5::create_grid_dataset(file_.get(), "/occupancy", H5T_STD_U8LE, dims, 1);
    h5::write_box(dataset.get(), H5T_NATIVE_UINT8, cells, 1, occupancy);
  } catch (const std::exception& e) {
    error = path() + ": occupancy: " + e.what();
  }
  file_.raise_if_any(error);
  has_occupancy_ = true;
  commit();
}

void FrameWriter::write_frame(double time, int step, const NodeBox& nodes, const double* x,
                              const double* v) {
  const std::string where = path() + ": frame at step " + std::to_string(step) + ": ";
  std::string problem = box_problem(nodes, meta_.node_dims, {x, v});
  if (problem.empty() && file_.rank() == 0) {
    // A frame that does not fit is refused before it touches the file: HDF5 may not close a
    // file whose write failed cleanly, and the frames before it must stay readable.
    const double bytes = 2.0 * 3 * sizeof(double) * static_cast<double>(meta_.node_dims[0]) *
                             static_cast<double>(meta_.node_dims[1]) *
                             static_cast<double>(meta_.node_dims[2]) +
                         65536.0;
    const std::string cause = write_failure_cause(path(), static_cast<std::uintmax_t>(bytes));
    if (!cause.empty())
      problem = "not written (it needs about " + std::to_string(static_cast<long long>(bytes)) +
                " bytes): " + cause + "; the " + std::to_string(frames_.size()) +
                " frame(s) before it are intact";
  }
  file_.raise_if_any(problem.empty() ? "" : where + problem);
  const int index = frames_.empty() ? 0 : frames_.back().index + 1;
  file_.write_group(frame_group(index), where, [&](hid_t group) {
    h5::write_attr(group, "time", time);
    h5::write_attr(group, "step", static_cast<long>(step));
    h5::Handle position =
        h5::create_grid_dataset(group, "position", H5T_IEEE_F64LE, meta_.node_dims, 3);
    h5::write_box(position.get(), H5T_NATIVE_DOUBLE, nodes, 3, x);
    h5::Handle velocity =
        h5::create_grid_dataset(group, "velocity", H5T_IEEE_F64LE, meta_.node_dims, 3);
    h5::write_box(velocity.get(), H5T_NATIVE_DOUBLE, nodes, 3, v);
  });
  frames_.push_back({index, step, time});
  commit();
}

void FrameWriter::close() {
  file_.close();
}

}  // namespace gen4d::io
