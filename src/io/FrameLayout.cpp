#include "io/FrameLayout.hpp"

#include <algorithm>
#include <cctype>
#include <cstdio>

#include "core/Error.hpp"
#include "io/Hdf5.hpp"

namespace gen4d::io {
namespace {

const char* const kReserved[] = {"format", "format_version", "node_dims", "origin", "spacing"};

bool is_reserved(const std::string& name) {
  return std::find(std::begin(kReserved), std::end(kReserved), name) != std::end(kReserved);
}

bool all_digits(const std::string& s) {
  return !s.empty() &&
         std::all_of(s.begin(), s.end(), [](unsigned char c) { return std::isdigit(c); });
}

}  // namespace

std::string frame_group(int index) {
  char name[16];
  std::snprintf(name, sizeof name, "%06d", index);
  return std::string(kFramesGroup) + "/" + name;
}

void write_grid_meta(hid_t file, const GridMeta& meta) {
  for (const auto& [name, value] : meta.attributes) {
    if (is_reserved(name)) {
      throw RuntimeError("frames file attribute '" + name + "' is reserved for the grid layout");
    }
    h5::write_attr(file, name, value);
  }
  h5::write_attr(file, "format", std::string(kFramesFormat));
  h5::write_attr(file, "format_version", kFramesFormatVersion);
  h5::write_attr(file, "node_dims", meta.node_dims);
  h5::write_attr(file, "origin", meta.origin);
  h5::write_attr(file, "spacing", meta.spacing);
}

GridMeta read_grid_meta(hid_t file, const std::string& file_name) {
  h5::check_format(file, file_name, "frames file", kFramesFormat, kFramesFormatVersion,
                   kFramesFormatVersion);
  GridMeta meta;
  meta.node_dims = h5::read_long3_attr(file, "node_dims", file_name);
  for (long n : meta.node_dims) {
    if (n < 2) throw InputError(file_name + ": node_dims must be at least 2 along every axis");
  }
  meta.origin = h5::read_double3_attr(file, "origin", file_name);
  meta.spacing = h5::read_double_attr(file, "spacing", file_name);
  for (const std::string& name : h5::attr_names(file)) {
    if (!is_reserved(name) && h5::attr_is_string(file, name)) {
      meta.attributes[name] = h5::read_string_attr(file, name, file_name);
    }
  }
  return meta;
}

std::vector<FrameInfo> list_frames(hid_t file, const std::string& file_name) {
  std::vector<FrameInfo> frames;
  if (!h5::link_exists(file, kFramesGroup)) return frames;
  h5::Handle group = h5::open_group(file, kFramesGroup, h5::Failure::Input, file_name);
  std::vector<std::string> names;
  H5L_iterate_t collect = [](hid_t, const char* name, const auto*, void* out) -> herr_t {
    static_cast<std::vector<std::string>*>(out)->emplace_back(name);
    return 0;
  };
  h5::check(H5Literate(group.get(), H5_INDEX_NAME, H5_ITER_INC, nullptr, collect, &names),
            h5::Failure::Input, file_name + ": cannot list " + kFramesGroup);
  for (const std::string& name : names) {
    if (!all_digits(name)) {
      throw InputError(file_name + ": unexpected entry " + kFramesGroup + "/" + name);
    }
    FrameInfo info;
    info.index = std::stoi(name);
    h5::Handle frame = h5::open_group(group.get(), name, h5::Failure::Input, file_name);
    const std::string where = file_name + " " + kFramesGroup + "/" + name;
    info.time = h5::read_double_attr(frame.get(), "time", where);
    info.step = static_cast<int>(h5::read_long_attr(frame.get(), "step", where));
    frames.push_back(info);
  }
  std::sort(frames.begin(), frames.end(),
            [](const FrameInfo& a, const FrameInfo& b) { return a.index < b.index; });
  return frames;
}

}  // namespace gen4d::io
