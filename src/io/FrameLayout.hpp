//! Layout of a gen4d frames file: grid metadata on the root group, the occupancy dataset, and
//! one group per frame (kFramesGroup + "/NNNNNN").
#pragma once

#include <hdf5.h>

#include <array>
#include <map>
#include <string>
#include <vector>

namespace gen4d::io {

//! The group holding one subgroup per frame.
inline constexpr const char* kFramesGroup = "/frames";

inline constexpr const char* kFramesFormat = "gen4d-frames";
inline constexpr long kFramesFormatVersion = 1;

//! The grid a frames file describes, plus free-form provenance (deck text, version, ranks).
struct GridMeta {
  std::array<long, 3> node_dims{0, 0, 0};  //!< nodes along x, y, z
  std::array<double, 3> origin{0, 0, 0};   //!< rest position of node (0, 0, 0)
  double spacing = 0;                      //!< voxel edge length h
  std::map<std::string, std::string> attributes;
};

//! One stored frame. `index` numbers its group under kFramesGroup (six digits).
struct FrameInfo {
  int index = 0;
  int step = 0;
  double time = 0;
};

//! The group of frame `index`: kFramesGroup, a slash, and the index in six digits.
std::string frame_group(int index);

//! Writes the grid metadata on the root group (collective). Throws RuntimeError.
void write_grid_meta(hid_t file, const GridMeta& meta);
//! Reads and checks the root-group metadata; InputError naming `file_name` when it is not
//! a gen4d frames file of a supported version.
GridMeta read_grid_meta(hid_t file, const std::string& file_name);
//! Frames stored under /frames, ordered by index; InputError naming `file_name` when damaged.
std::vector<FrameInfo> list_frames(hid_t file, const std::string& file_name);

}  // namespace gen4d::io
