//! Small HDF5 container of named double arrays plus text and number attributes: the on-disk
//! form of NeuralMTL weights and of the weight generator.
//
// Layout: one HDF5 file, root attributes `format` (text) and `format_version` (integer), any
// further text or number attributes, and one dataset per array at the root (float64, any rank).
// Writes go to a hidden temporary beside the target and are renamed into place, so a failed
// write never leaves a half-written file under the final name.
#pragma once

#include <map>
#include <string>
#include <vector>

namespace gen4d::neural {

struct NamedArray {
  std::vector<long> shape;   //!< row-major; empty for a scalar
  std::vector<double> data;  //!< product(shape) values
};

struct ArrayFile {
  std::string format;  //!< e.g. "gen4d-neuralmtl"
  long format_version = 1;
  std::map<std::string, std::string> text;  //!< text attributes
  std::map<std::string, double> numbers;    //!< number attributes
  std::map<std::string, NamedArray> arrays;

  //! The array `name`, checked to have `shape` (entries < 0 match any extent); InputError
  //! naming `file` and the array otherwise.
  const NamedArray& array(const std::string& name, const std::vector<long>& shape,
                          const std::string& file) const;
  const std::string& text_attr(const std::string& name, const std::string& file) const;
  double number_attr(const std::string& name, const std::string& file) const;
};

//! Writes `contents` to `path` (serial, atomic by rename). RuntimeError naming the path.
void write_array_file(const std::string& path, const ArrayFile& contents);

//! Reads `path`, checks `format` == expected_format and format_version <= max_version, and that
//! every array is finite. InputError naming the file (and dataset) on any problem.
ArrayFile read_array_file(const std::string& path, const std::string& expected_format,
                          long max_version);

}  // namespace gen4d::neural
