// PLY / OBJ surface files: writers (atomic) and strict readers with located errors.
#include "io/SurfaceIO.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/Error.hpp"
#include "io/AtomicFile.hpp"
#include "core/TextFile.hpp"

namespace gen4d::io {
namespace fs = std::filesystem;

namespace {

// ---- little-endian encoding ---------------------------------------------------------------

bool host_is_little_endian() {
  const std::uint16_t one = 1;
  std::uint8_t first = 0;
  std::memcpy(&first, &one, 1);
  return first == 1;
}

template <class T>
void put_le(std::string& out, T value) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  if (!host_is_little_endian()) std::reverse(bytes, bytes + sizeof(T));
  out.append(bytes, sizeof(T));
}

template <class T>
T get_le(const char* p) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, p, sizeof(T));
  if (!host_is_little_endian()) std::reverse(bytes, bytes + sizeof(T));
  T value;
  std::memcpy(&value, bytes, sizeof(T));
  return value;
}

std::string one_line(const std::string& text) {
  std::string out = text;
  for (char& c : out)
    if (c == '\n' || c == '\r') c = ' ';
  return out;
}

std::string ply_bytes(const SurfaceMesh& mesh) {
  std::string out = "ply\nformat binary_little_endian 1.0\n";
  for (const auto& c : mesh.comments) out += "comment " + one_line(c) + "\n";
  out += fmt::format(
      "element vertex {}\nproperty double x\nproperty double y\nproperty double z\n"
      "element face {}\nproperty list uchar int vertex_indices\nend_header\n",
      mesh.vertex_count(), mesh.triangles.size());
  out.reserve(out.size() + 8 * mesh.xyz.size() + 13 * mesh.triangles.size());
  for (double v : mesh.xyz) put_le(out, v);
  for (const auto& t : mesh.triangles) {
    put_le(out, std::uint8_t{3});
    for (std::int32_t i : t) put_le(out, i);
  }
  return out;
}

std::string obj_bytes(const SurfaceMesh& mesh) {
  fmt::memory_buffer out;
  for (const auto& c : mesh.comments)
    fmt::format_to(std::back_inserter(out), "# {}\n", one_line(c));
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v)
    fmt::format_to(std::back_inserter(out), "v {} {} {}\n", mesh.xyz[3 * v], mesh.xyz[3 * v + 1],
                   mesh.xyz[3 * v + 2]);
  for (const auto& t : mesh.triangles)
    fmt::format_to(std::back_inserter(out), "f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
  return std::string(out.data(), out.size());
}

bool parse_long(const std::string& token, long& value) {
  const char* begin = token.c_str();
  char* end = nullptr;
  errno = 0;
  value = std::strtol(begin, &end, 10);
  return end != begin && *end == '\0' && errno != ERANGE;
}

// ---- PLY ----------------------------------------------------------------------------------

enum class PlyType { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

template <class T>
double read_as_double(const char* p) {
  return static_cast<double>(get_le<T>(p));
}

//! A PLY scalar type: its two names, its size and its little-endian reader.
struct PlyTypeInfo {
  PlyType type;
  const char* names[2];
  std::size_t size;
  double (*read)(const char*);
};

//! In PlyType's order.
const PlyTypeInfo kPlyTypes[] = {
    {PlyType::Int8, {"char", "int8"}, 1, read_as_double<std::int8_t>},
    {PlyType::UInt8, {"uchar", "uint8"}, 1, read_as_double<std::uint8_t>},
    {PlyType::Int16, {"short", "int16"}, 2, read_as_double<std::int16_t>},
    {PlyType::UInt16, {"ushort", "uint16"}, 2, read_as_double<std::uint16_t>},
    {PlyType::Int32, {"int", "int32"}, 4, read_as_double<std::int32_t>},
    {PlyType::UInt32, {"uint", "uint32"}, 4, read_as_double<std::uint32_t>},
    {PlyType::Float32, {"float", "float32"}, 4, read_as_double<float>},
    {PlyType::Float64, {"double", "float64"}, 8, read_as_double<double>}};

bool ply_type(const std::string& name, PlyType& type) {
  for (const PlyTypeInfo& info : kPlyTypes)
    if (name == info.names[0] || name == info.names[1]) {
      type = info.type;
      return true;
    }
  return false;
}

std::size_t ply_size(PlyType t) {
  return kPlyTypes[static_cast<int>(t)].size;
}

double ply_value(PlyType t, const char* p) {
  return kPlyTypes[static_cast<int>(t)].read(p);
}

struct PlyProperty {
  std::string name;
  bool is_list = false;
  PlyType count_type = PlyType::UInt8;
  PlyType type = PlyType::Float64;
};

struct PlyElement {
  std::string name;
  long count = 0;
  std::vector<PlyProperty> properties;
};

//! Reads one element instance's property values, from binary bytes or from ascii tokens.
class PlyCursor {
 public:
  PlyCursor(const std::string& path, const std::string& bytes, std::size_t pos, bool binary,
            long header_lines)
      : path_(path), bytes_(bytes), pos_(pos), binary_(binary), line_(header_lines) {}

  //! Starts instance `index` of `element` (for ascii: reads its line).
  void begin(const PlyElement& element, long index) {
    where_ = fmt::format("{} {}", element.name, index);
    if (binary_) return;
    tokens_.clear();
    next_token_ = 0;
    while (tokens_.empty()) {
      if (pos_ >= bytes_.size())
        fail(fmt::format("file ends early ({} {} element(s) declared)", element.count,
                         element.name));
      std::size_t end = bytes_.find('\n', pos_);
      if (end == std::string::npos) end = bytes_.size();
      tokens_ = split_whitespace(bytes_.substr(pos_, end - pos_));
      pos_ = end + 1;
      ++line_;
    }
  }
  double scalar(PlyType type) {
    if (binary_) {
      const std::size_t n = ply_size(type);
      if (pos_ + n > bytes_.size()) fail("file is truncated (binary data ends here)");
      const double v = ply_value(type, bytes_.data() + pos_);
      pos_ += n;
      return v;
    }
    if (next_token_ >= tokens_.size()) fail("too few values on the line");
    double v = 0;
    const std::string& token = tokens_[next_token_++];
    if (!parse_double(token, v)) fail("not a number: " + quote_token(token));
    if ((type != PlyType::Float32 && type != PlyType::Float64) && v != std::floor(v))
      fail("not an integer: " + quote_token(token));
    return v;
  }
  void end() {
    if (!binary_ && next_token_ != tokens_.size())
      fail(fmt::format("{} value(s) more than its properties declare",
                       tokens_.size() - next_token_));
  }
  [[noreturn]] void fail(const std::string& message) const {
    if (binary_) throw InputError(fmt::format("{}: {}: {}", path_, where_, message));
    throw InputError(fmt::format("{}:{}: {}: {}", path_, line_, where_, message));
  }

 private:
  const std::string& path_;
  const std::string& bytes_;
  std::size_t pos_;
  bool binary_;
  long line_;
  std::string where_;
  std::vector<std::string> tokens_;
  std::size_t next_token_ = 0;
};

}  // namespace

const char* surface_extension(SurfaceFormat format) {
  return format == SurfaceFormat::Ply ? "ply" : "obj";
}

bool parse_surface_format(const std::string& name, SurfaceFormat& format) {
  if (name == "ply") {
    format = SurfaceFormat::Ply;
    return true;
  }
  if (name == "obj") {
    format = SurfaceFormat::Obj;
    return true;
  }
  return false;
}

std::string surface_file_name(long index, SurfaceFormat format) {
  return fmt::format("surface_{:06d}.{}", index, surface_extension(format));
}

std::string surface_bytes(const SurfaceMesh& mesh, SurfaceFormat format) {
  return format == SurfaceFormat::Ply ? ply_bytes(mesh) : obj_bytes(mesh);
}

void write_surface(const std::string& path, const SurfaceMesh& mesh, SurfaceFormat format) {
  const std::string bytes = surface_bytes(mesh, format);
  write_atomically(path, bytes);
}

SurfaceMesh read_ply(const std::string& path) {
  const std::string bytes = read_whole_file(path, "surface file");
  // Header: text lines up to "end_header".
  LineReader lines(bytes);

  auto header_error = [&](const std::string& message) {
    // The first line's number even when the file is empty.
    return InputError(
        fmt::format("{}:{}: PLY header: {}", path, std::max(1L, lines.number()), message));
  };
  std::string line;
  if (!lines.next(line) || line != "ply")
    throw header_error("not a PLY file (the first line must be 'ply')");
  SurfaceMesh mesh;
  bool binary = false, have_format = false;
  std::vector<PlyElement> elements;
  while (true) {
    if (!lines.next(line)) throw header_error("file ends before 'end_header'");
    const auto t = split_whitespace(line);
    if (t.empty()) continue;
    if (t[0] == "end_header") break;
    if (t[0] == "comment" || t[0] == "obj_info") {
      if (t[0] == "comment") mesh.comments.push_back(line.size() > 8 ? line.substr(8) : "");
      continue;
    }
    if (t[0] == "format") {
      if (t.size() != 3 || t[2] != "1.0") throw header_error("expected 'format <type> 1.0'");
      if (t[1] == "ascii")
        binary = false;
      else if (t[1] == "binary_little_endian")
        binary = true;
      else
        throw header_error("format " + quote_token(t[1]) +
                           " is not supported (ascii or binary_little_endian)");
      have_format = true;
    } else if (t[0] == "element") {
      long count = 0;
      if (t.size() != 3 || !parse_long(t[2], count) || count < 0)
        throw header_error("expected 'element <name> <count>' with a count >= 0");
      elements.push_back({t[1], count, {}});
    } else if (t[0] == "property") {
      if (elements.empty()) throw header_error("property before any element");
      PlyProperty p;
      if (t.size() == 5 && t[1] == "list") {
        p.is_list = true;
        if (!ply_type(t[2], p.count_type) || !ply_type(t[3], p.type))
          throw header_error("unknown type in " + quote_token(line));
        p.name = t[4];
      } else if (t.size() == 3) {
        if (!ply_type(t[1], p.type)) throw header_error("unknown type " + quote_token(t[1]));
        p.name = t[2];
      } else {
        throw header_error(
            "expected 'property <type> <name>' or 'property list <count type> "
            "<type> <name>'");
      }
      elements.back().properties.push_back(p);
    } else {
      throw header_error("unknown header keyword " + quote_token(t[0]));
    }
  }
  if (!have_format) throw header_error("no 'format' line before 'end_header'");

  long vertex_count = -1;
  std::vector<std::vector<long>> polygons;
  PlyCursor cursor(path, bytes, lines.position(), binary, lines.number());
  for (const PlyElement& element : elements) {
    const bool is_vertex = element.name == "vertex", is_face = element.name == "face";
    int xyz[3] = {-1, -1, -1}, list = -1;
    for (std::size_t i = 0; i < element.properties.size(); ++i) {
      const PlyProperty& p = element.properties[i];
      for (int a = 0; a < 3; ++a)
        if (is_vertex && !p.is_list && p.name == std::string(1, char('x' + a)))
          xyz[a] = static_cast<int>(i);
      if (is_face && p.is_list && (p.name == "vertex_indices" || p.name == "vertex_index"))
        list = static_cast<int>(i);
    }
    if (is_vertex) {
      for (int a = 0; a < 3; ++a)
        if (xyz[a] < 0)
          throw InputError(fmt::format("{}: PLY header: element vertex has no scalar property '{}'",
                                       path, char('x' + a)));
      vertex_count = element.count;
      mesh.xyz.reserve(3 * element.count);
    }
    if (is_face && list < 0 && element.count > 0)
      throw InputError(path + ": PLY header: element face has no list property vertex_indices");
    for (long n = 0; n < element.count; ++n) {
      cursor.begin(element, n);
      double point[3] = {0, 0, 0};
      std::vector<long> polygon;
      for (std::size_t i = 0; i < element.properties.size(); ++i) {
        const PlyProperty& p = element.properties[i];
        if (p.is_list) {
          const double count = cursor.scalar(p.count_type);
          if (count < 0 || count > 1e6)
            cursor.fail(fmt::format("list length {} is invalid", count));
          for (long c = 0; c < static_cast<long>(count); ++c) {
            const double v = cursor.scalar(p.type);
            if (static_cast<int>(i) == list) polygon.push_back(static_cast<long>(v));
          }
        } else {
          const double v = cursor.scalar(p.type);
          for (int a = 0; a < 3; ++a)
            if (static_cast<int>(i) == xyz[a]) point[a] = v;
        }
      }
      cursor.end();
      if (is_vertex) {
        for (double v : point)
          if (!std::isfinite(v)) cursor.fail("coordinate is not finite");
        mesh.xyz.insert(mesh.xyz.end(), point, point + 3);
      }
      if (is_face) {
        if (polygon.size() < 3)
          cursor.fail(fmt::format("a face needs at least 3 vertices, got {}", polygon.size()));
        polygons.push_back(std::move(polygon));
      }
    }
  }
  if (vertex_count < 0) throw InputError(path + ": PLY header: no vertex element");
  for (std::size_t f = 0; f < polygons.size(); ++f) {
    for (long v : polygons[f])
      if (v < 0 || v >= vertex_count)
        throw InputError(fmt::format("{}: face {}: vertex index {} out of range ({} vertices)",
                                     path, f, v, vertex_count));
    for (std::size_t c = 1; c + 1 < polygons[f].size(); ++c)
      mesh.triangles.push_back({static_cast<std::int32_t>(polygons[f][0]),
                                static_cast<std::int32_t>(polygons[f][c]),
                                static_cast<std::int32_t>(polygons[f][c + 1])});
  }
  return mesh;
}

SurfaceMesh read_obj_surface(const std::string& path) {
  const std::string bytes = read_whole_file(path, "surface file");
  SurfaceMesh mesh;
  std::istringstream in(bytes);
  std::string line;
  long line_no = 0;
  auto fail = [&](const std::string& message) {
    throw InputError(fmt::format("{}:{}: {}", path, line_no, message));
  };
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (!line.empty() && line[0] == '#') {
      mesh.comments.push_back(line.size() > 2 ? line.substr(2) : "");
      continue;
    }
    const auto t = split_whitespace(line);
    if (t.empty()) continue;
    if (t[0] == "v") {
      if (t.size() < 4) fail("a vertex needs 3 coordinates");
      for (int a = 1; a <= 3; ++a) {
        double v = 0;
        if (!parse_double(t[a], v) || !std::isfinite(v))
          fail("vertex coordinate " + quote_token(t[a]) + " is not a finite number");
        mesh.xyz.push_back(v);
      }
    } else if (t[0] == "f") {
      if (t.size() < 4) fail("a face needs at least 3 vertices");
      std::vector<std::int32_t> ids;
      const long n = static_cast<long>(mesh.vertex_count());
      for (std::size_t c = 1; c < t.size(); ++c) {
        long v = 0;
        const std::string first = t[c].substr(0, t[c].find('/'));
        if (!parse_long(first, v) || v == 0)
          fail("face index " + quote_token(t[c]) + " is invalid");
        const long id = v > 0 ? v - 1 : n + v;
        if (id < 0 || id >= n)
          fail(fmt::format("face index {} out of range ({} vertices so far)", v, n));
        ids.push_back(static_cast<std::int32_t>(id));
      }
      for (std::size_t c = 1; c + 1 < ids.size(); ++c)
        mesh.triangles.push_back({ids[0], ids[c], ids[c + 1]});
    }
  }
  return mesh;
}

SurfaceMesh read_surface(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext == ".ply") return read_ply(path);
  if (ext == ".obj") return read_obj_surface(path);
  throw InputError(path + ": not a surface file (expected .ply or .obj)");
}

namespace {

//! Index of "surface_<digits>.ply|obj", or -1.
long sequence_index(const std::string& name) {
  const std::string prefix = "surface_";
  if (name.size() < prefix.size() + 5 || name.compare(0, prefix.size(), prefix) != 0) return -1;
  const std::string ext = name.substr(name.size() - 4);
  if (ext != ".ply" && ext != ".obj") return -1;
  const std::string digits = name.substr(prefix.size(), name.size() - prefix.size() - 4);
  if (digits.empty() || digits.size() > 12) return -1;
  for (char c : digits)
    if (!std::isdigit(static_cast<unsigned char>(c))) return -1;
  return std::stol(digits);
}

bool is_sequence_temporary(const std::string& name) {
  return name.size() > 14 && name.compare(0, 9, ".surface_") == 0 &&
         name.compare(name.size() - 4, 4, ".tmp") == 0;
}

}  // namespace

std::vector<SurfaceFrameFile> list_surface_sequence(const std::string& dir) {
  std::vector<SurfaceFrameFile> out;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return out;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const long index = sequence_index(entry.path().filename().string());
    if (index >= 0 && entry.is_regular_file(ec)) out.push_back({index, entry.path().string()});
  }
  std::sort(out.begin(), out.end(), [](const SurfaceFrameFile& a, const SurfaceFrameFile& b) {
    return a.index != b.index ? a.index < b.index : a.path < b.path;
  });
  // One file per index (a .ply before an .obj of the same frame).
  out.erase(std::unique(out.begin(), out.end(),
                        [](const SurfaceFrameFile& a, const SurfaceFrameFile& b) {
                          return a.index == b.index;
                        }),
            out.end());
  return out;
}

int prune_surface_sequence(const std::string& dir, long keep_up_to) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return 0;
  std::vector<fs::path> doomed;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string name = entry.path().filename().string();
    const long index = sequence_index(name);
    if ((index >= 0 && index > keep_up_to) || is_sequence_temporary(name))
      doomed.push_back(entry.path());
  }
  for (const auto& p : doomed) {
    fs::remove(p, ec);
    if (ec) throw RuntimeError(p.string() + ": cannot remove: " + ec.message());
  }
  return static_cast<int>(doomed.size());
}

}  // namespace gen4d::io
