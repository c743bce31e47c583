#include "io/Checkpoint.hpp"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <thread>

#include "core/Error.hpp"
#include "core/Log.hpp"
#include "io/AtomicFile.hpp"
#include "io/BytePack.hpp"
#include "io/Hdf5.hpp"

namespace gen4d::io {
namespace fs = std::filesystem;
namespace {

std::string padded(int step) {
  char text[32];
  std::snprintf(text, sizeof text, "%08d", step);
  return text;
}

//! (step, path) of every checkpoint_<digits>.h5 in `dir`.
std::vector<std::pair<long, std::string>> list_checkpoints(const std::string& dir) {
  std::vector<std::pair<long, std::string>> found;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    const std::string prefix = "checkpoint_", suffix = ".h5";
    if (name.size() <= prefix.size() + suffix.size() || name.rfind(prefix, 0) != 0 ||
        name.compare(name.size() - suffix.size(), suffix.size(), suffix) != 0) {
      continue;
    }
    const std::string digits =
        name.substr(prefix.size(), name.size() - prefix.size() - suffix.size());
    if (digits.size() > 18 || !std::all_of(digits.begin(), digits.end(),
                                           [](unsigned char c) { return std::isdigit(c); })) {
      continue;
    }
    found.emplace_back(std::stol(digits), it->path().string());
  }
  std::sort(found.begin(), found.end());
  return found;
}

}  // namespace

void prune_checkpoints(const std::string& dir, int keep) {
  if (keep <= 0) return;
  auto found = list_checkpoints(dir);
  for (std::size_t i = 0; i + keep < found.size(); ++i) {
    std::error_code ec;
    if (!fs::remove(found[i].second, ec)) {
      log::warn("cannot remove old checkpoint {}: {}", found[i].second, ec.message());
    }
  }
}

namespace {

void write_contents(hid_t file, const CheckpointState& s) {
  h5::write_attr(file, "format", std::string(kCheckpointFormat));
  h5::write_attr(file, "format_version", kCheckpointFormatVersion);
  write_run_clock(file, s);
  h5::write_attr(file, "node_dims", s.node_dims);
  for (const char* name : {"position", "velocity"}) {
    h5::Handle dataset = h5::create_grid_dataset(file, name, H5T_IEEE_F64LE, s.node_dims, 3);
    h5::write_box(dataset.get(), H5T_NATIVE_DOUBLE, s.owned, 3, name[0] == 'p' ? s.x : s.v);
  }
}

//! Rejects files that are not gen4d checkpoints of this version; returns the node dims.
std::array<long, 3> check_layout(hid_t file, const std::string& path) {
  h5::check_format(file, path, "checkpoint", kCheckpointFormat, kCheckpointFormatVersion,
                   kCheckpointFormatVersion);
  const std::array<long, 3> dims = h5::read_long3_attr(file, "node_dims", path);
  for (long n : dims) {
    if (n < 1) throw InputError(path + ": node_dims must be positive");
  }
  for (const char* name : {"/position", "/velocity"}) {
    h5::open_grid_dataset(file, name, H5T_FLOAT, dims, 3, path);
  }
  return dims;
}

CheckpointMeta read_meta_serial(const std::string& path) {
  h5::Handle file = h5::open_file_serial(path);
  CheckpointMeta meta;
  meta.node_dims = check_layout(file.get(), path);
  static_cast<RunClock&>(meta) = read_run_clock(file.get(), path);
  return meta;
}

std::string pack(const CheckpointMeta& m) {
  std::string buffer;
  pack_run_clock(buffer, m);
  bytes::put(buffer, m.node_dims);
  return buffer;
}

CheckpointMeta unpack(const std::string& buffer) {
  CheckpointMeta m;
  bytes::Unpacker in{buffer};
  unpack_run_clock(in, m);
  in.get(m.node_dims);
  return m;
}

//! Removes the hidden .checkpoint_<digits>.h5.tmp files in `dir`: a run killed while writing a
//! checkpoint leaves one, which no restart reads (latest_checkpoint lists checkpoint_* only).
//! Called before this run writes its own, so none of them is being written.
void remove_stale_temporaries(const std::string& dir) {
  std::error_code ec;
  std::vector<fs::path> stale;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    const std::string prefix = ".checkpoint_", suffix = ".h5.tmp";
    if (name.size() > prefix.size() + suffix.size() && name.rfind(prefix, 0) == 0 &&
        name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0)
      stale.push_back(it->path());
  }
  for (const fs::path& p : stale) {
    if (fs::remove(p, ec))
      log::warn("removed {}, an unfinished checkpoint of an interrupted run", p.string());
  }
}

//! Closes the unfinished checkpoint temporary `path` after a failed write (a full disk, most
//! often): rank 0 first truncates it, so the metadata HDF5 still writes while closing finds the
//! room the file's data held (HDF5 1.10 keeps a file that fails to close half open, and
//! crashes on it at MPI_Finalize). The caller removes the file. Collective.
void abandon(MPI_Comm comm, int rank, h5::Handle& file, const std::string& path) {
  if (rank == 0 && ::truncate(path.c_str(), 0) != 0 && errno != ENOENT)
    log::warn("cannot truncate {}: {}", path, std::strerror(errno));
  MPI_Barrier(comm);
  try {
    file.close(h5::Failure::Runtime, path + ": cannot close");
  } catch (const std::exception& e) {
    log::warn("{}", e.what());
  }
}

//! Test hook: GEN4D_TEST_SLOW_CHECKPOINT=SECONDS makes every checkpoint write wait that long
//! with its datasets written but the temporary not yet closed, so a test can kill a rank in
//! the middle of a checkpoint write. Unset (the default), nothing waits.
void test_slow_checkpoint() {
  const char* text = std::getenv("GEN4D_TEST_SLOW_CHECKPOINT");
  if (text == nullptr || *text == '\0') return;
  const double seconds = std::atof(text);
  if (seconds > 0) std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
}

}  // namespace

std::string checkpoint_path(const std::string& dir, int step) {
  return (fs::path(dir) / ("checkpoint_" + padded(step) + ".h5")).string();
}

void write_run_clock(hid_t file, const RunClock& c) {
  h5::write_attr(file, "step", static_cast<long>(c.step));
  h5::write_attr(file, "time", c.time);
  h5::write_attr(file, "frame_index", static_cast<long>(c.frame_index));
  h5::write_attr(file, "next_frame_time", c.next_frame_time);
  h5::write_attr(file, "deck", c.deck_text);
  h5::Handle extras = h5::create_group(file, "/extras");
  for (const auto& [name, value] : c.extras) h5::write_attr(extras.get(), name, value);
}

RunClock read_run_clock(hid_t file, const std::string& path) {
  RunClock c;
  c.step = static_cast<int>(h5::read_long_attr(file, "step", path));
  c.time = h5::read_double_attr(file, "time", path);
  c.frame_index = static_cast<int>(h5::read_long_attr(file, "frame_index", path));
  c.next_frame_time = h5::read_double_attr(file, "next_frame_time", path);
  c.deck_text = h5::read_string_attr(file, "deck", path);
  h5::Handle extras = h5::open_group(file, "/extras", h5::Failure::Input, path);
  for (const std::string& name : h5::attr_names(extras.get()))
    c.extras[name] = h5::read_double_attr(extras.get(), name, path + " /extras");
  return c;
}

void pack_run_clock(std::string& buffer, const RunClock& c) {
  bytes::put(buffer, c.step);
  bytes::put(buffer, c.time);
  bytes::put(buffer, c.frame_index);
  bytes::put(buffer, c.next_frame_time);
  bytes::put(buffer, c.deck_text);
  bytes::put(buffer, c.extras.size());
  for (const auto& [name, value] : c.extras) {
    bytes::put(buffer, name);
    bytes::put(buffer, value);
  }
}

void unpack_run_clock(bytes::Unpacker& in, RunClock& c) {
  in.get(c.step);
  in.get(c.time);
  in.get(c.frame_index);
  in.get(c.next_frame_time);
  in.get(c.deck_text);
  std::size_t count = 0;
  in.get(count);
  for (std::size_t i = 0; i < count; ++i) {
    std::string name;
    double value = 0;
    in.get(name);
    in.get(value);
    c.extras[name] = value;
  }
}

void prepare_checkpoint_dir(MPI_Comm comm, const std::string& dir, const std::string& local_error) {
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  std::string error = local_error;
  std::error_code ec;
  if (rank == 0 && error.empty() && !fs::is_directory(dir, ec) &&
      !fs::create_directories(dir, ec)) {
    error = dir + ": cannot create the checkpoint directory (" + ec.message() + ")";
  }
  if (rank == 0 && error.empty()) remove_stale_temporaries(dir);
  error = h5::first_error(comm, error);
  if (!error.empty()) throw RuntimeError(error);
}

std::string commit_checkpoint_file(MPI_Comm comm, const std::string& dir, int step, int keep,
                                   const std::function<void(hid_t)>& fill) {
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  const std::string final_path = checkpoint_path(dir, step);
  const std::string temp_path =
      (fs::path(dir) / (".checkpoint_" + padded(step) + ".h5.tmp")).string();
  // The fill and the close each end with the ranks agreeing, so that no rank goes on to a
  // collective close while another has failed.
  std::string error;
  h5::Handle file;
  const auto attempt = [&](const std::function<void()>& work) {
    if (!error.empty()) return;
    try {
      work();
    } catch (const std::exception& e) {
      const std::string cause = write_failure_cause(temp_path);
      error = final_path + ": cannot write the checkpoint (through " + temp_path +
              "): " + e.what() + (cause.empty() ? "" : "; " + cause);
    }
    error = h5::first_error(comm, error);
  };
  attempt([&] {
    file = h5::create_file(comm, temp_path);
    fill(file.get());
  });
  attempt([&] {
    test_slow_checkpoint();
    file.close(h5::Failure::Runtime, "cannot finish the file");
  });
  if (!error.empty()) abandon(comm, rank, file, temp_path);
  error = h5::first_error(comm, error);
  if (rank == 0) {
    if (error.empty() && std::rename(temp_path.c_str(), final_path.c_str()) != 0) {
      error = "cannot rename " + temp_path + " to " + final_path + ": " + std::strerror(errno);
    }
    if (error.empty()) {
      prune_checkpoints(dir, keep);
    } else {
      std::remove(temp_path.c_str());
    }
  }
  // Also the barrier after which every rank sees the renamed file.
  error = h5::first_error(comm, error);
  if (!error.empty()) throw RuntimeError(error);
  return final_path;
}

std::string write_checkpoint(MPI_Comm comm, const std::string& dir, const CheckpointState& state,
                             int keep) {
  const std::string final_path = checkpoint_path(dir, state.step);
  std::string error;
  if (!state.owned.inside(state.node_dims) ||
      (!state.owned.empty() && (state.x == nullptr || state.v == nullptr))) {
    error = final_path + ": this rank's node box is outside the grid or has no data";
  }
  prepare_checkpoint_dir(comm, dir, error);
  return commit_checkpoint_file(comm, dir, state.step, keep,
                                [&](hid_t file) { write_contents(file, state); });
}

CheckpointMeta read_checkpoint_meta(MPI_Comm comm, const std::string& path) {
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  h5::silence_errors();
  std::string packed, error;
  if (rank == 0) {
    try {
      packed = pack(read_meta_serial(path));
    } catch (const std::exception& e) {
      error = e.what();
    }
  }
  error = h5::first_error(comm, error);
  if (!error.empty()) throw InputError(error);
  unsigned long length = packed.size();
  MPI_Bcast(&length, 1, MPI_UNSIGNED_LONG, 0, comm);
  packed.resize(length);
  MPI_Bcast(packed.data(), static_cast<int>(length), MPI_CHAR, 0, comm);
  return unpack(packed);
}

void read_checkpoint_fields(MPI_Comm comm, const std::string& path, const NodeBox& owned,
                            std::vector<double>& x, std::vector<double>& v) {
  std::string error;
  h5::Handle file;
  std::array<long, 3> dims{};
  try {
    file = h5::open_file(comm, path, false);
    dims = check_layout(file.get(), path);
    if (!owned.inside(dims)) error = path + ": a rank's node box lies outside the checkpoint grid";
  } catch (const std::exception& e) {
    error = e.what();
  }
  error = h5::first_error(comm, error);
  if (!error.empty()) throw InputError(error);
  try {
    x.assign(3 * owned.size(), 0.0);
    v.assign(3 * owned.size(), 0.0);
    for (const char* name : {"/position", "/velocity"}) {
      h5::Handle dataset = h5::open_grid_dataset(file.get(), name, H5T_FLOAT, dims, 3, path);
      h5::read_box(dataset.get(), H5T_NATIVE_DOUBLE, owned, 3, name[1] == 'p' ? x.data() : v.data(),
                   path + ": cannot read dataset " + name);
    }
    file.close(h5::Failure::Input, path + ": cannot close");
  } catch (const std::exception& e) {
    error = e.what();
  }
  error = h5::first_error(comm, error);
  if (!error.empty()) throw InputError(error);
}

CheckpointMeta read_checkpoint(MPI_Comm comm, const std::string& path, const NodeBox& owned,
                               std::vector<double>& x, std::vector<double>& v) {
  CheckpointMeta meta = read_checkpoint_meta(comm, path);
  read_checkpoint_fields(comm, path, owned, x, v);
  return meta;
}

std::string latest_checkpoint(const std::string& dir) {
  auto found = list_checkpoints(dir);
  return found.empty() ? std::string() : found.back().second;
}

}  // namespace gen4d::io
