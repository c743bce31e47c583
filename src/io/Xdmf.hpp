//! XDMF index that lets ParaView and VisIt open a gen4d frames file as a time series.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "io/FrameLayout.hpp"

namespace gen4d::io {

//! The index path beside a frames file: run.h5 -> run.xdmf.
std::string xdmf_path_for(const std::string& h5_path);

//! XDMF text for `frames` of the frames file `h5_name` (named relative to the index):
//! a temporal collection of curvilinear (3DSMesh) grids whose geometry is the deformed node
//! positions, with node velocity and, when `with_occupancy`, the cell occupancy.
std::string xdmf_text(const std::string& h5_name, const std::array<long, 3>& node_dims,
                      const std::vector<FrameInfo>& frames, bool with_occupancy);

//! Replaces `path` by `text` through a temporary file and a rename, so a reader sees either
//! the old or the new index, never a partial one. Throws RuntimeError.
void write_text_atomically(const std::string& path, const std::string& text);

}  // namespace gen4d::io
