#include "io/Xdmf.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/Error.hpp"
#include "core/TextFile.hpp"
#include "io/AtomicFile.hpp"

namespace gen4d::io {
namespace {

std::string dims_text(const std::array<long, 3>& xyz, const char* tail = "") {
  return std::to_string(xyz[2]) + " " + std::to_string(xyz[1]) + " " + std::to_string(xyz[0]) +
         tail;
}

}  // namespace

std::string xml_escaped(const std::string& text) {
  return escaped(text, {{'&', "&amp;"}, {'<', "&lt;"}, {'>', "&gt;"}, {'"', "&quot;"}});
}

XdmfCollection::XdmfCollection(const std::string& name, const std::string& h5_name)
    : file_(xml_escaped(h5_name)) {
  out_.precision(17);  // times round-trip exactly
  out_ << "<?xml version=\"1.0\" ?>\n"
       << "<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n"
       << "<Xdmf Version=\"2.0\">\n"
       << "  <Domain>\n"
       << "    <Grid Name=\"" << name
       << "\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
}

void XdmfCollection::begin_grid(int index, double time, const std::string& topology) {
  out_ << "    <Grid Name=\"frame_" << index << "\" GridType=\"Uniform\">\n"
       << "      <Time Value=\"" << time << "\"/>\n"
       << "      <Topology " << topology << "/>\n";
}

void XdmfCollection::data_item(const std::string& dims, const char* number_type, int precision,
                               const std::string& dataset) {
  out_ << "        <DataItem Dimensions=\"" << dims << "\" NumberType=\"" << number_type
       << "\" Precision=\"" << precision << "\" Format=\"HDF\">" << file_ << ":" << dataset
       << "</DataItem>\n";
}

void XdmfCollection::geometry(const std::string& dims, const std::string& dataset) {
  out_ << "      <Geometry GeometryType=\"XYZ\">\n";
  data_item(dims, "Float", 8, dataset);
  out_ << "      </Geometry>\n";
}

void XdmfCollection::attribute(const std::string& name, const char* type, const char* center,
                               const std::string& dims, const char* number_type, int precision,
                               const std::string& dataset) {
  out_ << "      <Attribute Name=\"" << xml_escaped(name) << "\" AttributeType=\"" << type
       << "\" Center=\"" << center << "\">\n";
  data_item(dims, number_type, precision, dataset);
  out_ << "      </Attribute>\n";
}

void XdmfCollection::end_grid() {
  out_ << "    </Grid>\n";
}

std::string XdmfCollection::text() {
  out_ << "    </Grid>\n"
       << "  </Domain>\n"
       << "</Xdmf>\n";
  return out_.str();
}

std::string xdmf_path_for(const std::string& h5_path) {
  std::filesystem::path path(h5_path);
  if (path.extension() == ".h5" || path.extension() == ".hdf5") path.replace_extension();
  return path.string() + ".xdmf";
}

std::string xdmf_text(const std::string& h5_name, const std::array<long, 3>& node_dims,
                      const std::vector<FrameInfo>& frames, bool with_occupancy) {
  const std::string nodes = dims_text(node_dims);
  const std::string vectors = dims_text(node_dims, " 3");
  const std::string cells = dims_text({node_dims[0] - 1, node_dims[1] - 1, node_dims[2] - 1});
  XdmfCollection x("frames", h5_name);
  for (const FrameInfo& frame : frames) {
    const std::string group = frame_group(frame.index);
    x.begin_grid(frame.index, frame.time, "TopologyType=\"3DSMesh\" Dimensions=\"" + nodes + "\"");
    x.geometry(vectors, group + "/position");
    x.attribute("velocity", "Vector", "Node", vectors, "Float", 8, group + "/velocity");
    if (with_occupancy) x.attribute("occupancy", "Scalar", "Cell", cells, "UChar", 1, "/occupancy");
    x.end_grid();
  }
  return x.text();
}

void write_text_atomically(const std::string& path, const std::string& text) {
  const std::string error = try_write_atomically(path, text, path + ".tmp");
  if (!error.empty()) throw RuntimeError(error);
}

}  // namespace gen4d::io
