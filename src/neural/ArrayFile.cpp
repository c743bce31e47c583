#include "neural/ArrayFile.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>

#include "core/Error.hpp"
#include "io/Hdf5.hpp"

namespace gen4d::neural {
namespace h5 = gen4d::io::h5;
namespace {

std::string shape_text(const std::vector<long>& shape) {
  std::string s = "(";
  for (std::size_t i = 0; i < shape.size(); ++i)
    s += (i ? ", " : "") + (shape[i] < 0 ? std::string("any") : std::to_string(shape[i]));
  return s + ")";
}

herr_t collect_name(hid_t, const char* name, const H5L_info_t*, void* out) {
  static_cast<std::vector<std::string>*>(out)->emplace_back(name);
  return 0;
}

}  // namespace

const NamedArray& ArrayFile::array(const std::string& name, const std::vector<long>& shape,
                                   const std::string& file) const {
  auto it = arrays.find(name);
  if (it == arrays.end()) throw InputError(file + ": missing dataset '" + name + "'");
  bool ok = it->second.shape.size() == shape.size();
  for (std::size_t i = 0; ok && i < shape.size(); ++i)
    ok = shape[i] < 0 || shape[i] == it->second.shape[i];
  if (!ok)
    throw InputError(file + ": dataset '" + name + "' has shape " + shape_text(it->second.shape) +
                     ", expected " + shape_text(shape));
  return it->second;
}

const std::string& ArrayFile::text_attr(const std::string& name, const std::string& file) const {
  auto it = text.find(name);
  if (it == text.end()) throw InputError(file + ": missing text attribute '" + name + "'");
  return it->second;
}

double ArrayFile::number_attr(const std::string& name, const std::string& file) const {
  auto it = numbers.find(name);
  if (it == numbers.end()) throw InputError(file + ": missing number attribute '" + name + "'");
  return it->second;
}

void write_array_file(const std::string& path, const ArrayFile& contents) {
  namespace fs = std::filesystem;
  const fs::path final_path(path);
  const std::string temp =
      (final_path.parent_path() / ("." + final_path.filename().string() + ".tmp")).string();
  try {
    h5::silence_errors();
    h5::Handle file = h5::checked(H5Fcreate(temp.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT),
                                  H5Fclose, h5::Failure::Runtime, "cannot create " + temp);
    h5::write_attr(file.get(), "format", contents.format);
    h5::write_attr(file.get(), "format_version", contents.format_version);
    for (const auto& [name, value] : contents.text) h5::write_attr(file.get(), name, value);
    for (const auto& [name, value] : contents.numbers) h5::write_attr(file.get(), name, value);
    for (const auto& [name, a] : contents.arrays) {
      std::vector<hsize_t> dims(a.shape.begin(), a.shape.end());
      std::size_t count = 1;
      for (long d : a.shape) count *= static_cast<std::size_t>(d);
      if (count != a.data.size())
        throw RuntimeError(path + ": array '" + name + "' has " + std::to_string(a.data.size()) +
                           " values for shape " + shape_text(a.shape));
      h5::Handle space =
          dims.empty()
              ? h5::checked(H5Screate(H5S_SCALAR), H5Sclose, h5::Failure::Runtime, name)
              : h5::checked(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr),
                            H5Sclose, h5::Failure::Runtime, name);
      h5::Handle set = h5::checked(H5Dcreate2(file.get(), name.c_str(), H5T_IEEE_F64LE, space.get(),
                                              H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                                   H5Dclose, h5::Failure::Runtime, "cannot create " + name);
      if (!a.data.empty())
        h5::check(
            H5Dwrite(set.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, a.data.data()),
            h5::Failure::Runtime, "cannot write " + name);
    }
    file.close(h5::Failure::Runtime, "cannot close " + temp);
  } catch (const std::exception& e) {
    std::remove(temp.c_str());
    throw RuntimeError(path + ": " + e.what());
  }
  if (std::rename(temp.c_str(), path.c_str()) != 0) {
    std::remove(temp.c_str());
    throw RuntimeError(path + ": cannot rename " + temp + " into place");
  }
}

ArrayFile read_array_file(const std::string& path, const std::string& expected_format,
                          long max_version) {
  ArrayFile out;
  h5::Handle file = h5::open_file_serial(path);
  if (!h5::has_attr(file.get(), "format") || !h5::attr_is_string(file.get(), "format"))
    throw InputError(path + ": not a " + expected_format + " file (no 'format' attribute)");
  out.format = h5::read_string_attr(file.get(), "format", path);
  if (out.format != expected_format)
    throw InputError(path + ": format is '" + out.format + "', expected '" + expected_format + "'");
  out.format_version = h5::read_long_attr(file.get(), "format_version", path);
  if (out.format_version < 1 || out.format_version > max_version)
    throw InputError(path + ": format_version " + std::to_string(out.format_version) +
                     " is not supported (this build reads up to " + std::to_string(max_version) +
                     ")");
  for (const std::string& name : h5::attr_names(file.get())) {
    if (name == "format" || name == "format_version") continue;
    if (h5::attr_is_string(file.get(), name))
      out.text[name] = h5::read_string_attr(file.get(), name, path);
    else
      out.numbers[name] = h5::read_double_attr(file.get(), name, path);
  }
  std::vector<std::string> names;
  hsize_t idx = 0;
  h5::check(H5Literate(file.get(), H5_INDEX_NAME, H5_ITER_INC, &idx, collect_name, &names),
            h5::Failure::Input, path + ": cannot list datasets");
  for (const std::string& name : names) {
    h5::Handle set = h5::checked(H5Dopen2(file.get(), name.c_str(), H5P_DEFAULT), H5Dclose,
                                 h5::Failure::Input, path + ": '" + name + "' is not a dataset");
    h5::Handle type = h5::checked(H5Dget_type(set.get()), H5Tclose, h5::Failure::Input, name);
    if (H5Tget_class(type.get()) != H5T_FLOAT)
      throw InputError(path + ": dataset '" + name + "' is not floating point");
    h5::Handle space = h5::checked(H5Dget_space(set.get()), H5Sclose, h5::Failure::Input, name);
    const int rank = H5Sget_simple_extent_ndims(space.get());
    if (rank < 0 || rank > 8) throw InputError(path + ": dataset '" + name + "' has a bad shape");
    std::vector<hsize_t> dims(rank);
    if (rank > 0) H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr);
    NamedArray a;
    std::size_t count = 1;
    for (hsize_t d : dims) {
      a.shape.push_back(static_cast<long>(d));
      count *= d;
    }
    if (count > (std::size_t{1} << 28))
      throw InputError(path + ": dataset '" + name + "' is implausibly large");
    a.data.resize(count);
    if (count)
      h5::read_all(set.get(), H5T_NATIVE_DOUBLE, a.data.data(),
                   path + ": cannot read dataset '" + name + "'");
    for (double v : a.data)
      if (!std::isfinite(v))
        throw InputError(path + ": dataset '" + name + "' holds a non-finite value");
    out.arrays.emplace(name, std::move(a));
  }
  return out;
}

}  // namespace gen4d::neural
