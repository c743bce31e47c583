#include "io/Xdmf.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/Error.hpp"

namespace gen4d::io {
namespace {

std::string xml_escaped(const std::string& text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string dims_text(const std::array<long, 3>& xyz, const char* tail = "") {
  return std::to_string(xyz[2]) + " " + std::to_string(xyz[1]) + " " + std::to_string(xyz[0]) +
         tail;
}

void data_item(std::ostream& out, const std::string& dims, const char* number_type, int precision,
               const std::string& source) {
  out << "        <DataItem Dimensions=\"" << dims << "\" NumberType=\"" << number_type
      << "\" Precision=\"" << precision << "\" Format=\"HDF\">" << source << "</DataItem>\n";
}

}  // namespace

std::string xdmf_path_for(const std::string& h5_path) {
  std::filesystem::path path(h5_path);
  if (path.extension() == ".h5" || path.extension() == ".hdf5") path.replace_extension();
  return path.string() + ".xdmf";
}

std::string xdmf_text(const std::string& h5_name, const std::array<long, 3>& node_dims,
                      const std::vector<FrameInfo>& frames, bool with_occupancy) {
  const std::string file = xml_escaped(h5_name);
  const std::string nodes = dims_text(node_dims);
  const std::string vectors = dims_text(node_dims, " 3");
  const std::string cells = dims_text({node_dims[0] - 1, node_dims[1] - 1, node_dims[2] - 1});
  std::ostringstream out;
  out.precision(17);  // times round-trip exactly
  out << "<?xml version=\"1.0\" ?>\n"
      << "<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n"
      << "<Xdmf Version=\"2.0\">\n"
      << "  <Domain>\n"
      << "    <Grid Name=\"frames\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  for (const FrameInfo& frame : frames) {
    const std::string group = frame_group(frame.index);
    out << "    <Grid Name=\"frame_" << frame.index << "\" GridType=\"Uniform\">\n"
        << "      <Time Value=\"" << frame.time << "\"/>\n"
        << "      <Topology TopologyType=\"3DSMesh\" Dimensions=\"" << nodes << "\"/>\n"
        << "      <Geometry GeometryType=\"XYZ\">\n";
    data_item(out, vectors, "Float", 8, file + ":" + group + "/position");
    out << "      </Geometry>\n"
        << "      <Attribute Name=\"velocity\" AttributeType=\"Vector\" Center=\"Node\">\n";
    data_item(out, vectors, "Float", 8, file + ":" + group + "/velocity");
    out << "      </Attribute>\n";
    if (with_occupancy) {
      out << "      <Attribute Name=\"occupancy\" AttributeType=\"Scalar\" Center=\"Cell\">\n";
      data_item(out, cells, "UChar", 1, file + ":/occupancy");
      out << "      </Attribute>\n";
    }
    out << "    </Grid>\n";
  }
  out << "    </Grid>\n"
      << "  </Domain>\n"
      << "</Xdmf>\n";
  return out.str();
}

void write_text_atomically(const std::string& path, const std::string& text) {
  const std::string temp = path + ".tmp";
  {
    std::ofstream out(temp, std::ios::binary | std::ios::trunc);
    out << text;
    out.close();
    if (!out) {
      std::remove(temp.c_str());
      throw RuntimeError("cannot write " + temp);
    }
  }
  if (std::rename(temp.c_str(), path.c_str()) != 0) {
    std::remove(temp.c_str());
    throw RuntimeError("cannot rename " + temp + " to " + path);
  }
}

}  // namespace gen4d::io
