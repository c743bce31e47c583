#include "io/Hdf5.hpp"

#include <algorithm>
#include <filesystem>
#include <sstream>
#include <type_traits>

#include "core/Error.hpp"

namespace gen4d::io::h5 {
namespace {

herr_t innermost_error(unsigned n, const H5E_error2_t* err, void* out) {
  auto* text = static_cast<std::string*>(out);
  if (n == 0 && err->desc != nullptr) *text = err->desc;
  return 0;
}

//! The description HDF5 recorded closest to the failure ("truncated file: eof = ...").
std::string hdf5_error_detail() {
  std::string text;
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, innermost_error, &text);
  for (char& c : text) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  return text;
}

[[noreturn]] void raise(Failure kind, const std::string& message) {
  if (kind == Failure::Input) throw InputError(message);
  throw RuntimeError(message);
}

std::string shape_text(const std::vector<hsize_t>& shape) {
  std::ostringstream s;
  s << '[';
  for (std::size_t a = 0; a < shape.size(); ++a) s << (a ? " " : "") << shape[a];
  s << ']';
  return s.str();
}

Handle open_attr(hid_t obj, const std::string& name, const std::string& file) {
  if (!has_attr(obj, name)) raise(Failure::Input, file + ": missing attribute '" + name + "'");
  return checked(H5Aopen(obj, name.c_str(), H5P_DEFAULT), H5Aclose, Failure::Input,
                 file + ": cannot open attribute '" + name + "'");
}

//! Opens a numeric attribute of `n` values, rejecting text and arrays of another length.
Handle open_numeric_attr(hid_t obj, const std::string& name, hssize_t n, bool integer,
                         const std::string& file) {
  Handle attr = open_attr(obj, name, file);
  Handle type = checked(H5Aget_type(attr.get()), H5Tclose, Failure::Input, file + ": " + name);
  Handle space = checked(H5Aget_space(attr.get()), H5Sclose, Failure::Input, file + ": " + name);
  H5T_class_t cls = H5Tget_class(type.get());
  bool ok_class = integer ? cls == H5T_INTEGER : (cls == H5T_FLOAT || cls == H5T_INTEGER);
  if (!ok_class || H5Sget_simple_extent_npoints(space.get()) != n) {
    raise(Failure::Input, file + ": attribute '" + name + "' must hold " + std::to_string(n) +
                              (integer ? " integer" : " number") + (n == 1 ? "" : "s"));
  }
  return attr;
}

void write_attr_raw(hid_t obj, const std::string& name, hid_t file_type, hid_t mem_type, hsize_t n,
                    const void* value) {
  if (has_attr(obj, name)) check(H5Adelete(obj, name.c_str()), Failure::Runtime, name);
  Handle space = n == 0
                     ? checked(H5Screate(H5S_SCALAR), H5Sclose, Failure::Runtime, name)
                     : checked(H5Screate_simple(1, &n, nullptr), H5Sclose, Failure::Runtime, name);
  Handle attr =
      checked(H5Acreate2(obj, name.c_str(), file_type, space.get(), H5P_DEFAULT, H5P_DEFAULT),
              H5Aclose, Failure::Runtime, "cannot create attribute '" + name + "'");
  check(H5Awrite(attr.get(), mem_type, value), Failure::Runtime,
        "cannot write attribute '" + name + "'");
}

}  // namespace

void fail(Failure kind, const std::string& message) {
  std::string detail = hdf5_error_detail();
  raise(kind, detail.empty() ? message : message + " (" + detail + ")");
}

void silence_errors() {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
}

Handle& Handle::operator=(Handle&& other) noexcept {
  if (this != &other) {
    release();
    id_ = other.id_;
    closer_ = other.closer_;
    other.id_ = -1;
  }
  return *this;
}

void Handle::release() {
  if (id_ >= 0 && closer_ != nullptr) closer_(id_);
  id_ = -1;
}

void Handle::close(Failure kind, const std::string& what) {
  if (id_ < 0) return;
  herr_t status = closer_(id_);
  id_ = -1;
  check(status, kind, what);
}

Handle checked(hid_t id, Handle::Closer closer, Failure kind, const std::string& what) {
  if (id < 0) fail(kind, what);
  return Handle(id, closer);
}

void check(herr_t status, Failure kind, const std::string& what) {
  if (status < 0) fail(kind, what);
}

Handle mpio_access(MPI_Comm comm) {
  Handle fapl = checked(H5Pcreate(H5P_FILE_ACCESS), H5Pclose, Failure::Runtime, "H5Pcreate");
  check(H5Pset_fapl_mpio(fapl.get(), comm, MPI_INFO_NULL), Failure::Runtime, "H5Pset_fapl_mpio");
  // The 1.8 format stores large attributes (a long deck text) densely; 1.8+ readers open it.
  check(H5Pset_libver_bounds(fapl.get(), H5F_LIBVER_V18, H5F_LIBVER_V18), Failure::Runtime,
        "H5Pset_libver_bounds");
  return fapl;
}

Handle collective_transfer() {
  Handle dxpl = checked(H5Pcreate(H5P_DATASET_XFER), H5Pclose, Failure::Runtime, "H5Pcreate");
  check(H5Pset_dxpl_mpio(dxpl.get(), H5FD_MPIO_COLLECTIVE), Failure::Runtime, "H5Pset_dxpl_mpio");
  return dxpl;
}

Handle create_file(MPI_Comm comm, const std::string& path) {
  silence_errors();
  Handle fapl = mpio_access(comm);
  return checked(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.get()), H5Fclose,
                 Failure::Runtime, "cannot create the file");
}

namespace {
//! Explains why `path` did not open: missing, not HDF5, or damaged.
[[noreturn]] void explain_open_failure(const std::string& path) {
  std::string detail = hdf5_error_detail();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) raise(Failure::Input, path + ": no such file");
  if (!std::filesystem::is_regular_file(path, ec)) raise(Failure::Input, path + ": not a file");
  if (H5Fis_hdf5(path.c_str()) <= 0) raise(Failure::Input, path + ": not an HDF5 file");
  raise(Failure::Input, path + ": damaged or truncated HDF5 file" +
                            (detail.empty() ? std::string() : " (" + detail + ")"));
}
}  // namespace

Handle open_file(MPI_Comm comm, const std::string& path, bool writable) {
  silence_errors();
  Handle fapl = mpio_access(comm);
  hid_t id = H5Fopen(path.c_str(), writable ? H5F_ACC_RDWR : H5F_ACC_RDONLY, fapl.get());
  if (id < 0) explain_open_failure(path);
  return Handle(id, H5Fclose);
}

Handle open_file_serial(const std::string& path) {
  silence_errors();
  hid_t id = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (id < 0) explain_open_failure(path);
  return Handle(id, H5Fclose);
}

Handle open_group(hid_t loc, const std::string& name, Failure kind, const std::string& file) {
  if (!link_exists(loc, name)) raise(kind, file + ": missing group " + name);
  return checked(H5Gopen2(loc, name.c_str(), H5P_DEFAULT), H5Gclose, kind,
                 file + ": cannot open group " + name);
}

Handle create_group(hid_t loc, const std::string& name) {
  return checked(H5Gcreate2(loc, name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose,
                 Failure::Runtime, "cannot create group " + name);
}

bool link_exists(hid_t loc, const std::string& path) {
  // H5Lexists fails rather than answering "no" when an intermediate group is missing.
  std::size_t pos = path.front() == '/' ? 1 : 0;
  while (pos <= path.size()) {
    std::size_t next = path.find('/', pos);
    if (next == std::string::npos) next = path.size();
    if (H5Lexists(loc, path.substr(0, next).c_str(), H5P_DEFAULT) <= 0) return false;
    pos = next + 1;
  }
  return true;
}

void write_attr(hid_t obj, const std::string& name, const std::string& value) {
  Handle type = checked(H5Tcopy(H5T_C_S1), H5Tclose, Failure::Runtime, name);
  check(H5Tset_size(type.get(), value.size() + 1), Failure::Runtime, name);
  check(H5Tset_strpad(type.get(), H5T_STR_NULLTERM), Failure::Runtime, name);
  write_attr_raw(obj, name, type.get(), type.get(), 0, value.c_str());
}

void write_attr(hid_t obj, const std::string& name, double value) {
  write_attr_raw(obj, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, 0, &value);
}

void write_attr(hid_t obj, const std::string& name, long value) {
  write_attr_raw(obj, name, H5T_STD_I64LE, H5T_NATIVE_LONG, 0, &value);
}

void write_attr(hid_t obj, const std::string& name, const std::array<long, 3>& value) {
  write_attr_raw(obj, name, H5T_STD_I64LE, H5T_NATIVE_LONG, 3, value.data());
}

void write_attr(hid_t obj, const std::string& name, const std::array<double, 3>& value) {
  write_attr_raw(obj, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, 3, value.data());
}

bool has_attr(hid_t obj, const std::string& name) {
  return H5Aexists(obj, name.c_str()) > 0;
}

long check_format(hid_t file, const std::string& path, const std::string& kind,
                  const std::string& format, long min_version, long max_version) {
  if (!has_attr(file, "format"))
    throw InputError(path + ": not a gen4d " + kind + " (no 'format' attribute)");
  const std::string found = read_string_attr(file, "format", path);
  if (found != format)
    throw InputError(path + ": not a gen4d " + kind + " (format is '" + found + "', expected '" +
                     format + "')");
  const long version = read_long_attr(file, "format_version", path);
  if (version < min_version || version > max_version) {
    const std::string expected = min_version == max_version ? std::to_string(max_version)
                                                            : std::to_string(min_version) + " to " +
                                                                  std::to_string(max_version);
    throw InputError(path + ": " + kind + " format_version " + std::to_string(version) +
                     " is not supported (expected " + expected + ")");
  }
  return version;
}

std::vector<std::string> attr_names(hid_t obj) {
  std::vector<std::string> names;
  auto collect = [](hid_t, const char* name, const H5A_info_t*, void* out) -> herr_t {
    static_cast<std::vector<std::string>*>(out)->emplace_back(name);
    return 0;
  };
  H5Aiterate2(obj, H5_INDEX_NAME, H5_ITER_INC, nullptr, collect, &names);
  return names;
}

bool attr_is_string(hid_t obj, const std::string& name) {
  Handle attr(H5Aopen(obj, name.c_str(), H5P_DEFAULT), H5Aclose);
  if (attr.get() < 0) return false;
  Handle type(H5Aget_type(attr.get()), H5Tclose);
  return type.get() >= 0 && H5Tget_class(type.get()) == H5T_STRING;
}

std::string read_string_attr(hid_t obj, const std::string& name, const std::string& file) {
  Handle attr = open_attr(obj, name, file);
  Handle type = checked(H5Aget_type(attr.get()), H5Tclose, Failure::Input, file + ": " + name);
  Handle space = checked(H5Aget_space(attr.get()), H5Sclose, Failure::Input, file + ": " + name);
  if (H5Tget_class(type.get()) != H5T_STRING || H5Sget_simple_extent_npoints(space.get()) != 1) {
    raise(Failure::Input, file + ": attribute '" + name + "' must be one string");
  }
  std::string what = file + ": cannot read attribute '" + name + "'";
  if (H5Tis_variable_str(type.get()) > 0) {
    Handle mem = checked(H5Tcopy(H5T_C_S1), H5Tclose, Failure::Input, what);
    check(H5Tset_size(mem.get(), H5T_VARIABLE), Failure::Input, what);
    char* text = nullptr;
    check(H5Aread(attr.get(), mem.get(), &text), Failure::Input, what);
    std::string value = text != nullptr ? text : "";
    H5free_memory(text);
    return value;
  }
  std::string buffer(H5Tget_size(type.get()), '\0');
  check(H5Aread(attr.get(), type.get(), buffer.data()), Failure::Input, what);
  return buffer.substr(0, buffer.find('\0'));
}

namespace {
//! N values of a long or double attribute.
template <class T, std::size_t N>
std::array<T, N> read_numeric_attr(hid_t obj, const std::string& name, const std::string& file) {
  constexpr bool integer = std::is_same_v<T, long>;
  Handle attr = open_numeric_attr(obj, name, static_cast<hssize_t>(N), integer, file);
  std::array<T, N> value{};
  check(H5Aread(attr.get(), integer ? H5T_NATIVE_LONG : H5T_NATIVE_DOUBLE, value.data()),
        Failure::Input, file + ": cannot read attribute '" + name + "'");
  return value;
}
}  // namespace

double read_double_attr(hid_t obj, const std::string& name, const std::string& file) {
  return read_numeric_attr<double, 1>(obj, name, file)[0];
}

long read_long_attr(hid_t obj, const std::string& name, const std::string& file) {
  return read_numeric_attr<long, 1>(obj, name, file)[0];
}

std::array<long, 3> read_long3_attr(hid_t obj, const std::string& name, const std::string& file) {
  return read_numeric_attr<long, 3>(obj, name, file);
}

std::array<double, 3> read_double3_attr(hid_t obj, const std::string& name,
                                        const std::string& file) {
  return read_numeric_attr<double, 3>(obj, name, file);
}

std::vector<hsize_t> grid_shape(const std::array<long, 3>& dims, int components) {
  std::vector<hsize_t> shape{static_cast<hsize_t>(dims[2]), static_cast<hsize_t>(dims[1]),
                             static_cast<hsize_t>(dims[0])};
  if (components > 1) shape.push_back(static_cast<hsize_t>(components));
  return shape;
}

namespace {
//! A dataset of `shape` (C order) at `name`. RuntimeError naming it.
Handle create_dataset(hid_t loc, const std::string& name, hid_t type,
                      const std::vector<hsize_t>& shape) {
  Handle space = checked(H5Screate_simple(static_cast<int>(shape.size()), shape.data(), nullptr),
                         H5Sclose, Failure::Runtime, "cannot describe dataset " + name);
  return checked(
      H5Dcreate2(loc, name.c_str(), type, space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
      H5Dclose, Failure::Runtime, "cannot create dataset " + name);
}
}  // namespace

Handle create_grid_dataset(hid_t loc, const std::string& name, hid_t type,
                           const std::array<long, 3>& dims, int components) {
  return create_dataset(loc, name, type, grid_shape(dims, components));
}

namespace {
//! Opens dataset `path` and checks that its shape is `expected` and its type `type_class`.
Handle open_shaped_dataset(hid_t loc, const std::string& path, H5T_class_t type_class,
                           const std::vector<hsize_t>& expected, const std::string& file) {
  if (!link_exists(loc, path)) raise(Failure::Input, file + ": missing dataset " + path);
  std::string what = file + ": cannot open dataset " + path;
  Handle dataset =
      checked(H5Dopen2(loc, path.c_str(), H5P_DEFAULT), H5Dclose, Failure::Input, what);
  Handle type = checked(H5Dget_type(dataset.get()), H5Tclose, Failure::Input, what);
  Handle space = checked(H5Dget_space(dataset.get()), H5Sclose, Failure::Input, what);
  int rank = H5Sget_simple_extent_ndims(space.get());
  std::vector<hsize_t> shape(rank > 0 ? rank : 0);
  if (rank > 0) H5Sget_simple_extent_dims(space.get(), shape.data(), nullptr);
  if (shape != expected) {
    raise(Failure::Input, file + ": dataset " + path + " has shape " + shape_text(shape) +
                              ", expected " + shape_text(expected));
  }
  if (H5Tget_class(type.get()) != type_class) {
    raise(Failure::Input, file + ": dataset " + path + " has the wrong element type (expected " +
                              (type_class == H5T_FLOAT ? "floating point" : "integer") + ")");
  }
  return dataset;
}
}  // namespace

Handle open_grid_dataset(hid_t loc, const std::string& path, H5T_class_t type_class,
                         const std::array<long, 3>& dims, int components, const std::string& file) {
  return open_shaped_dataset(loc, path, type_class, grid_shape(dims, components), file);
}

namespace {
//! File and memory selections of the block at `start` of shape `count` in `dataset`; `empty`
//! selects nothing.
std::pair<Handle, Handle> block_selection(hid_t dataset, const std::vector<hsize_t>& start,
                                          const std::vector<hsize_t>& count, bool empty,
                                          Failure kind, const std::string& what) {
  Handle file_space = checked(H5Dget_space(dataset), H5Sclose, kind, what);
  if (empty) {
    hsize_t one = 1;
    Handle mem_space = checked(H5Screate_simple(1, &one, nullptr), H5Sclose, kind, what);
    check(H5Sselect_none(file_space.get()), kind, what);
    check(H5Sselect_none(mem_space.get()), kind, what);
    return {std::move(file_space), std::move(mem_space)};
  }
  check(H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start.data(), nullptr, count.data(),
                            nullptr),
        kind, what);
  Handle mem_space =
      checked(H5Screate_simple(static_cast<int>(count.size()), count.data(), nullptr), H5Sclose,
              kind, what);
  return {std::move(file_space), std::move(mem_space)};
}

//! File and memory selections of `box` in a grid dataset; an empty box selects nothing.
std::pair<Handle, Handle> box_selection(hid_t dataset, const NodeBox& box, int components,
                                        Failure kind, const std::string& what) {
  std::vector<hsize_t> start{static_cast<hsize_t>(box.start[2]), static_cast<hsize_t>(box.start[1]),
                             static_cast<hsize_t>(box.start[0])};
  if (components > 1) start.push_back(0);
  return block_selection(dataset, start, grid_shape(box.count, components), box.empty(), kind,
                         what);
}
}  // namespace

void write_box(hid_t dataset, hid_t mem_type, const NodeBox& box, int components,
               const void* data) {
  const std::string what = "cannot write a dataset";
  auto [file_space, mem_space] = box_selection(dataset, box, components, Failure::Runtime, what);
  Handle dxpl = collective_transfer();
  static const double nothing = 0;  // HDF5 rejects a null buffer even for an empty selection
  check(H5Dwrite(dataset, mem_type, mem_space.get(), file_space.get(), dxpl.get(),
                 box.empty() ? &nothing : data),
        Failure::Runtime, what);
}

void read_box(hid_t dataset, hid_t mem_type, const NodeBox& box, int components, void* data,
              const std::string& what) {
  auto [file_space, mem_space] = box_selection(dataset, box, components, Failure::Input, what);
  Handle dxpl = collective_transfer();
  double nothing = 0;
  check(H5Dread(dataset, mem_type, mem_space.get(), file_space.get(), dxpl.get(),
                box.empty() ? &nothing : data),
        Failure::Input, what);
}

void read_all(hid_t dataset, hid_t mem_type, void* data, const std::string& what) {
  check(H5Dread(dataset, mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), Failure::Input, what);
}

std::vector<hsize_t> rows_shape(hsize_t rows, int width) {
  std::vector<hsize_t> shape{rows};
  if (width > 1) shape.push_back(static_cast<hsize_t>(width));
  return shape;
}

Handle create_rows_dataset(hid_t loc, const std::string& name, hid_t type, hsize_t rows,
                           int width) {
  return create_dataset(loc, name, type, rows_shape(rows, width));
}

Handle open_rows_dataset(hid_t loc, const std::string& path, H5T_class_t type_class, hsize_t rows,
                         int width, const std::string& file) {
  return open_shaped_dataset(loc, path, type_class, rows_shape(rows, width), file);
}

namespace {
//! File and memory selections of rows [start, start + count); no rows selects nothing.
std::pair<Handle, Handle> rows_selection(hid_t dataset, hsize_t start, hsize_t count, int width,
                                         Failure kind, const std::string& what) {
  std::vector<hsize_t> offset{start};
  if (width > 1) offset.push_back(0);
  return block_selection(dataset, offset, rows_shape(count, width), count == 0, kind, what);
}
}  // namespace

void write_rows(hid_t dataset, hid_t mem_type, hsize_t start, hsize_t count, int width,
                const void* data) {
  const std::string what = "cannot write a dataset";
  auto [file_space, mem_space] =
      rows_selection(dataset, start, count, width, Failure::Runtime, what);
  // A dataset without rows has no storage to write to (and every rank knows it).
  if (H5Sget_simple_extent_npoints(file_space.get()) == 0) return;
  Handle dxpl = collective_transfer();
  static const double nothing = 0;  // HDF5 rejects a null buffer even for an empty selection
  check(H5Dwrite(dataset, mem_type, mem_space.get(), file_space.get(), dxpl.get(),
                 count == 0 ? &nothing : data),
        Failure::Runtime, what);
}

void read_rows(hid_t dataset, hid_t mem_type, hsize_t start, hsize_t count, int width, void* data,
               const std::string& what) {
  auto [file_space, mem_space] = rows_selection(dataset, start, count, width, Failure::Input, what);
  if (H5Sget_simple_extent_npoints(file_space.get()) == 0) return;
  Handle dxpl = collective_transfer();
  double nothing = 0;
  check(H5Dread(dataset, mem_type, mem_space.get(), file_space.get(), dxpl.get(),
                count == 0 ? &nothing : data),
        Failure::Input, what);
}

void write_string_list_attr(hid_t obj, const std::string& name,
                            const std::vector<std::string>& values) {
  if (has_attr(obj, name)) check(H5Adelete(obj, name.c_str()), Failure::Runtime, name);
  std::size_t longest = 0;
  for (const std::string& v : values) longest = std::max(longest, v.size());
  Handle type = checked(H5Tcopy(H5T_C_S1), H5Tclose, Failure::Runtime, name);
  check(H5Tset_size(type.get(), longest + 1), Failure::Runtime, name);
  check(H5Tset_strpad(type.get(), H5T_STR_NULLTERM), Failure::Runtime, name);
  hsize_t n = values.size();
  Handle space = n == 0
                     ? checked(H5Screate(H5S_NULL), H5Sclose, Failure::Runtime, name)
                     : checked(H5Screate_simple(1, &n, nullptr), H5Sclose, Failure::Runtime, name);
  Handle attr =
      checked(H5Acreate2(obj, name.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT),
              H5Aclose, Failure::Runtime, "cannot create attribute '" + name + "'");
  if (n == 0) return;
  std::string buffer(n * (longest + 1), '\0');
  for (std::size_t i = 0; i < n; ++i) values[i].copy(&buffer[i * (longest + 1)], values[i].size());
  check(H5Awrite(attr.get(), type.get(), buffer.data()), Failure::Runtime,
        "cannot write attribute '" + name + "'");
}

std::vector<std::string> read_string_list_attr(hid_t obj, const std::string& name,
                                               const std::string& file) {
  Handle attr = open_attr(obj, name, file);
  Handle type = checked(H5Aget_type(attr.get()), H5Tclose, Failure::Input, file + ": " + name);
  Handle space = checked(H5Aget_space(attr.get()), H5Sclose, Failure::Input, file + ": " + name);
  const H5S_class_t space_class = H5Sget_simple_extent_type(space.get());
  if (H5Tget_class(type.get()) != H5T_STRING ||
      (space_class != H5S_NULL && H5Sget_simple_extent_ndims(space.get()) != 1)) {
    raise(Failure::Input, file + ": attribute '" + name + "' must be a list of strings");
  }
  std::vector<std::string> values;
  if (space_class == H5S_NULL) return values;
  const hssize_t n = H5Sget_simple_extent_npoints(space.get());
  std::string what = file + ": cannot read attribute '" + name + "'";
  if (H5Tis_variable_str(type.get()) > 0) {
    Handle mem = checked(H5Tcopy(H5T_C_S1), H5Tclose, Failure::Input, what);
    check(H5Tset_size(mem.get(), H5T_VARIABLE), Failure::Input, what);
    std::vector<char*> texts(static_cast<std::size_t>(n), nullptr);
    check(H5Aread(attr.get(), mem.get(), texts.data()), Failure::Input, what);
    for (char* text : texts) {
      values.emplace_back(text != nullptr ? text : "");
      H5free_memory(text);
    }
    return values;
  }
  const std::size_t size = H5Tget_size(type.get());
  std::string buffer(static_cast<std::size_t>(n) * size, '\0');
  check(H5Aread(attr.get(), type.get(), buffer.data()), Failure::Input, what);
  for (hssize_t i = 0; i < n; ++i) {
    std::string text = buffer.substr(static_cast<std::size_t>(i) * size, size);
    values.push_back(text.substr(0, text.find('\0')));
  }
  return values;
}

std::string first_error(MPI_Comm comm, const std::string& local_error) {
  int rank = 0, size = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &size);
  int mine = local_error.empty() ? size : rank;
  int first = size;
  MPI_Allreduce(&mine, &first, 1, MPI_INT, MPI_MIN, comm);
  if (first == size) return "";
  std::string message = local_error;
  unsigned long length = message.size();
  MPI_Bcast(&length, 1, MPI_UNSIGNED_LONG, first, comm);
  message.resize(length);
  MPI_Bcast(message.data(), static_cast<int>(length), MPI_CHAR, first, comm);
  return message;
}

}  // namespace gen4d::io::h5
