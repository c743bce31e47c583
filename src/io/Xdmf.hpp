//! XDMF index that lets ParaView and VisIt open a gen4d frames file as a time series.
#pragma once

#include <array>
#include <sstream>
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

//! `text` with XML's special characters escaped.
std::string xml_escaped(const std::string& text);

//! XDMF text of a temporal collection of grids, one per frame, whose data live in the HDF5
//! file `h5_name` (named relative to the index): what every gen4d index shares.
class XdmfCollection {
 public:
  XdmfCollection(const std::string& name, const std::string& h5_name);
  //! Opens frame `index`'s grid at `time`; `topology` holds the Topology element's attributes.
  void begin_grid(int index, double time, const std::string& topology);
  //! XYZ geometry from the float64 dataset (`dims` in XDMF order, slowest first).
  void geometry(const std::string& dims, const std::string& dataset);
  //! An attribute of `type` (Scalar, Vector) centred on `center` (Node, Cell).
  void attribute(const std::string& name, const char* type, const char* center,
                 const std::string& dims, const char* number_type, int precision,
                 const std::string& dataset);
  void end_grid();
  //! The whole text (closes the collection).
  std::string text();

 private:
  void data_item(const std::string& dims, const char* number_type, int precision,
                 const std::string& dataset);
  std::ostringstream out_;
  std::string file_;
};

//! Replaces `path` by `text` through a temporary file and a rename, so a reader sees either
//! the old or the new index, never a partial one. Throws RuntimeError.
void write_text_atomically(const std::string& path, const std::string& text);

}  // namespace gen4d::io
