#include "io/FramesFile.hpp"

#include <filesystem>

#include "core/Error.hpp"
#include "io/AtomicFile.hpp"
#include "io/FrameLayout.hpp"
#include "io/Xdmf.hpp"

namespace gen4d::io {
namespace {

//! "; no space left on device (...)" when that is why writing `path` failed, else "".
std::string cause_of(const std::string& path) {
  const std::string cause = write_failure_cause(path);
  return cause.empty() ? "" : "; " + cause;
}

}  // namespace

FramesFile::FramesFile(MPI_Comm comm, const std::string& h5_path, h5::Handle file)
    : comm_(comm), path_(h5_path), xdmf_path_(xdmf_path_for(h5_path)), file_(std::move(file)) {
  MPI_Comm_rank(comm_, &rank_);
}

FramesFile FramesFile::create(MPI_Comm comm, const std::string& h5_path,
                              const std::function<void(hid_t)>& fill_root) {
  FramesFile f(comm, h5_path, h5::Handle());
  std::string error;
  try {
    f.file_ = h5::create_file(comm, h5_path);
    fill_root(f.file_.get());
    h5::create_group(f.file_.get(), kFramesGroup);
  } catch (const std::exception& e) {
    error = h5_path + ": " + e.what() + cause_of(h5_path);
  }
  f.raise_if_any(error);
  return f;
}

void FramesFile::raise_if_any(const std::string& local_error) const {
  const std::string error = h5::first_error(comm_, local_error);
  if (!error.empty()) throw RuntimeError(error);
}

void FramesFile::write_group(const std::string& group_name, const std::string& where,
                             const std::function<void(hid_t)>& fill) {
  std::string error;
  try {
    h5::Handle group = h5::create_group(file_.get(), group_name);
    fill(group.get());
  } catch (const std::exception& e) {
    error = where + e.what() + cause_of(path_);
  }
  error = h5::first_error(comm_, error);
  if (error.empty()) return;
  if (h5::link_exists(file_.get(), group_name))
    H5Ldelete(file_.get(), group_name.c_str(), H5P_DEFAULT);
  throw RuntimeError(error);
}

void FramesFile::remove_group(const std::string& group_name) {
  // Unlinking is collective metadata work, identical on every rank.
  h5::check(H5Ldelete(file_.get(), group_name.c_str(), H5P_DEFAULT), h5::Failure::Runtime,
            path_ + ": cannot delete " + group_name);
}

void FramesFile::commit(const std::function<std::string(const std::string&)>& index_text) {
  h5::check(H5Fflush(file_.get(), H5F_SCOPE_GLOBAL), h5::Failure::Runtime,
            path_ + ": cannot flush");
  std::string error;
  if (rank_ == 0) {
    try {
      write_text_atomically(xdmf_path_,
                            index_text(std::filesystem::path(path_).filename().string()));
    } catch (const std::exception& e) {
      error = e.what();
    }
  }
  raise_if_any(error);
}

void FramesFile::close() {
  file_.close(h5::Failure::Runtime, path_ + ": cannot close");
}

}  // namespace gen4d::io
