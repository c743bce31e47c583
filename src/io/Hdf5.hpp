//! Thin RAII and error-reporting layer over the HDF5 C API shared by frames and checkpoints.
#pragma once

#include <hdf5.h>
#include <mpi.h>

#include <array>
#include <string>
#include <vector>

#include "io/GridBox.hpp"

namespace gen4d::io::h5 {

//! Which gen4d error a failed HDF5 call turns into: bad input (reading) or a runtime failure.
enum class Failure { Input, Runtime };

//! Throws InputError or RuntimeError with `message`, adding HDF5's innermost error description.
[[noreturn]] void fail(Failure kind, const std::string& message);

//! Turns HDF5's automatic error-stack printing off so users see only gen4d's one-line messages.
void silence_errors();

//! Owns one HDF5 identifier and closes it with the matching H5?close function.
class Handle {
 public:
  using Closer = herr_t (*)(hid_t);
  Handle() = default;
  Handle(hid_t id, Closer closer) : id_(id), closer_(closer) {}
  ~Handle() { release(); }
  Handle(Handle&& other) noexcept : id_(other.id_), closer_(other.closer_) { other.id_ = -1; }
  Handle& operator=(Handle&& other) noexcept;
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;

  hid_t get() const { return id_; }
  //! Closes now and reports failure; a file's close is where buffered data reach the disk.
  void close(Failure kind, const std::string& what);

 private:
  void release();
  hid_t id_ = -1;
  Closer closer_ = nullptr;
};

//! Checks an identifier returned by HDF5; on failure throws with `what`.
Handle checked(hid_t id, Handle::Closer closer, Failure kind, const std::string& what);
//! Checks a status returned by HDF5; on failure throws with `what`.
void check(herr_t status, Failure kind, const std::string& what);

//! File access through MPI-IO on `comm` (every rank of `comm` must open the file).
Handle mpio_access(MPI_Comm comm);
//! Collective data transfer: every rank joins each read and write, possibly with nothing.
Handle collective_transfer();

//! Creates (truncating) `path` collectively on `comm`; failures are RuntimeErrors that
//! callers prefix with the path.
Handle create_file(MPI_Comm comm, const std::string& path);
//! Opens `path` collectively on `comm`; failures are InputErrors naming the file.
Handle open_file(MPI_Comm comm, const std::string& path, bool writable);
//! Opens `path` read-only on this process alone; failures are InputErrors naming the file.
Handle open_file_serial(const std::string& path);

Handle open_group(hid_t loc, const std::string& name, Failure kind, const std::string& file);
Handle create_group(hid_t loc, const std::string& name);
bool link_exists(hid_t loc, const std::string& path);

// Attributes. Writers run collectively with equal values on every rank; readers name `file`.
void write_attr(hid_t obj, const std::string& name, const std::string& value);
void write_attr(hid_t obj, const std::string& name, double value);
void write_attr(hid_t obj, const std::string& name, long value);
void write_attr(hid_t obj, const std::string& name, const std::array<long, 3>& value);
void write_attr(hid_t obj, const std::string& name, const std::array<double, 3>& value);
bool has_attr(hid_t obj, const std::string& name);
std::vector<std::string> attr_names(hid_t obj);
//! True when the attribute holds text (fixed or variable length).
bool attr_is_string(hid_t obj, const std::string& name);
std::string read_string_attr(hid_t obj, const std::string& name, const std::string& file);
double read_double_attr(hid_t obj, const std::string& name, const std::string& file);
long read_long_attr(hid_t obj, const std::string& name, const std::string& file);
std::array<long, 3> read_long3_attr(hid_t obj, const std::string& name, const std::string& file);
std::array<double, 3> read_double3_attr(hid_t obj, const std::string& name,
                                        const std::string& file);
//! Checks the `format` and `format_version` attributes of a gen4d file against `format` and
//! min_version..max_version; returns the version. InputError "FILE: not a gen4d KIND (...)" or
//! "FILE: KIND format_version N is not supported (expected ...)".
long check_format(hid_t file, const std::string& path, const std::string& kind,
                  const std::string& format, long min_version, long max_version);

// Datasets over the global grid: C order [nz][ny][nx] plus a trailing [components] when > 1.
std::vector<hsize_t> grid_shape(const std::array<long, 3>& dims, int components);
Handle create_grid_dataset(hid_t loc, const std::string& name, hid_t type,
                           const std::array<long, 3>& dims, int components);
//! Opens `path` and checks its shape and type class; InputError naming file and dataset.
Handle open_grid_dataset(hid_t loc, const std::string& path, H5T_class_t type_class,
                         const std::array<long, 3>& dims, int components, const std::string& file);
//! Collective write of this rank's box (x-fastest, `components` values per entry).
void write_box(hid_t dataset, hid_t mem_type, const NodeBox& box, int components, const void* data);
//! Collective read of this rank's box; failures are InputErrors naming `what`.
void read_box(hid_t dataset, hid_t mem_type, const NodeBox& box, int components, void* data,
              const std::string& what);
//! Serial read of a whole dataset into `data`; failures are InputErrors naming `what`.
void read_all(hid_t dataset, hid_t mem_type, void* data, const std::string& what);

// Datasets of rows indexed by a global id (particle arrays): shape [rows] when width is 1,
// else [rows][width]. Ranks write and read contiguous row ranges, so every decomposition
// writes the same file.
std::vector<hsize_t> rows_shape(hsize_t rows, int width);
Handle create_rows_dataset(hid_t loc, const std::string& name, hid_t type, hsize_t rows, int width);
//! Opens `path` and checks its shape and type class; InputError naming file and dataset.
Handle open_rows_dataset(hid_t loc, const std::string& path, H5T_class_t type_class, hsize_t rows,
                         int width, const std::string& file);
//! Collective write of rows [start, start + count) (`width` values per row, row-major).
void write_rows(hid_t dataset, hid_t mem_type, hsize_t start, hsize_t count, int width,
                const void* data);
//! Collective read of rows [start, start + count); failures are InputErrors naming `what`.
void read_rows(hid_t dataset, hid_t mem_type, hsize_t start, hsize_t count, int width, void* data,
               const std::string& what);

//! A one-dimensional attribute of strings (an empty list is stored with a null dataspace).
void write_string_list_attr(hid_t obj, const std::string& name,
                            const std::vector<std::string>& values);
std::vector<std::string> read_string_list_attr(hid_t obj, const std::string& name,
                                               const std::string& file);

//! Returns the first failing rank's message on every rank of `comm` ("" when all succeeded).
//! Lets a rank whose local step failed avoid leaving the others waiting in a collective call.
std::string first_error(MPI_Comm comm, const std::string& local_error);

}  // namespace gen4d::io::h5
