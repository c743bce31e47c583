// OBJ and STL readers. Every defect in a file becomes an InputError naming the file and the
// line (OBJ, ASCII STL) or triangle (STL); coordinates must be finite.
#include <fmt/format.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/Error.hpp"
#include "core/TextFile.hpp"
#include "geometry/Mesh.hpp"

namespace gen4d::geometry {
namespace {

// Parses a whole token as a finite double; returns false otherwise.
bool parse_finite(const std::string& token, double& value) {
  return parse_double(token, value) && std::isfinite(value);
}

struct ObjState {
  const std::string& path;
  Mesh mesh;
  long max_index = 0;  // largest positive index seen, checked once all vertices are known
  long max_index_line = 0;
};

void obj_vertex(ObjState& st, const std::vector<std::string>& tok, long line) {
  if (tok.size() < 4)
    throw InputError(fmt::format("{}:{}: vertex needs 3 coordinates", st.path, line));
  Eigen::Vector3d v;
  for (int d = 0; d < 3; ++d)
    if (!parse_finite(tok[d + 1], v[d]))
      throw InputError(
          fmt::format("{}:{}: bad number {} in vertex", st.path, line, quote_token(tok[d + 1])));
  st.mesh.vertices.push_back(v);
}

int obj_index(ObjState& st, const std::string& token, long line) {
  // Only the position index (before the first '/') matters here.
  const std::string pos = token.substr(0, token.find('/'));
  const char* begin = pos.c_str();
  char* end = nullptr;
  errno = 0;
  const long idx = std::strtol(begin, &end, 10);
  if (end == begin || *end != '\0' || errno == ERANGE || idx == 0 || idx > INT32_MAX)
    throw InputError(fmt::format("{}:{}: bad face index {}", st.path, line, quote_token(token)));
  const long nverts = static_cast<long>(st.mesh.vertices.size());
  if (idx < 0) {
    // Relative indices count back from the vertices read so far.
    if (nverts + idx < 0)
      throw InputError(fmt::format("{}:{}: face index {} out of range ({} vertices so far)",
                                   st.path, line, idx, nverts));
    return static_cast<int>(nverts + idx);
  }
  if (idx > st.max_index) {
    st.max_index = idx;
    st.max_index_line = line;
  }
  return static_cast<int>(idx - 1);
}

void obj_face(ObjState& st, const std::vector<std::string>& tok, long line) {
  if (tok.size() < 4)
    throw InputError(fmt::format("{}:{}: face needs at least 3 vertices", st.path, line));
  const int first = obj_index(st, tok[1], line);
  int prev = obj_index(st, tok[2], line);
  for (std::size_t t = 3; t < tok.size(); ++t) {
    const int cur = obj_index(st, tok[t], line);
    st.mesh.triangles.push_back({first, prev, cur});
    prev = cur;
  }
}

bool starts_with_solid(const std::string& bytes) {
  std::size_t i = 0;
  while (i < bytes.size() && std::isspace(static_cast<unsigned char>(bytes[i]))) ++i;
  if (bytes.size() - i < 5) return false;
  std::string word = bytes.substr(i, 5);
  for (char& c : word) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return word == "solid";
}

// ASCII STL starts with "solid" and holds only text; a binary file, even one whose header
// starts with "solid", has a little-endian triangle count (and floats) with bytes no text has.
bool looks_like_text(const std::string& bytes) {
  if (!starts_with_solid(bytes)) return false;
  const std::size_t n = std::min<std::size_t>(bytes.size(), 1024);
  for (std::size_t i = 0; i < n; ++i) {
    const auto c = static_cast<unsigned char>(bytes[i]);
    if (c >= 0x80 || (c < 0x20 && c != '\n' && c != '\r' && c != '\t')) return false;
  }
  return true;
}

Mesh parse_binary_stl(const std::string& path, const std::string& bytes) {
  std::uint32_t count = 0;
  std::memcpy(&count, bytes.data() + 80, 4);
  const std::size_t expected = 84 + 50 * static_cast<std::size_t>(count);
  if (bytes.size() < expected)
    throw InputError(fmt::format(
        "{}: truncated binary STL: header declares {} triangles, data ends in triangle {}", path,
        count, (bytes.size() - 84) / 50));
  if (bytes.size() > expected)
    throw InputError(
        fmt::format("{}: binary STL header declares {} triangles but {} bytes follow them", path,
                    count, bytes.size() - expected));
  Mesh mesh;
  mesh.vertices.reserve(3 * static_cast<std::size_t>(count));
  mesh.triangles.reserve(count);
  for (std::uint32_t t = 0; t < count; ++t) {
    const char* rec = bytes.data() + 84 + 50 * static_cast<std::size_t>(t) + 12;
    float xyz[9];
    std::memcpy(xyz, rec, sizeof(xyz));  // STL is little-endian, like every supported host
    const int base = static_cast<int>(mesh.vertices.size());
    for (int c = 0; c < 3; ++c) {
      Eigen::Vector3d v(xyz[3 * c], xyz[3 * c + 1], xyz[3 * c + 2]);
      if (!v.allFinite())
        throw InputError(fmt::format("{}: triangle {} has a non-finite coordinate", path, t));
      mesh.vertices.push_back(v);
    }
    mesh.triangles.push_back({base, base + 1, base + 2});
  }
  return mesh;
}

// ASCII STL is parsed record by record: solid / facet normal / outer loop / vertex x3 /
// endloop / endfacet / endsolid. Normals are ignored (orientation comes from vertex order).
Mesh parse_ascii_stl(const std::string& path, const std::string& bytes) {
  Mesh mesh;
  LineReader lines(bytes);
  std::string line;
  bool in_facet = false;
  int corners = 0;
  auto fail = [&](const std::string& what) {
    return InputError(
        fmt::format("{}:{}: triangle {}: {}", path, lines.number(), mesh.triangles.size(), what));
  };
  while (lines.next(line)) {
    const auto tok = split_whitespace(line);
    if (tok.empty()) continue;
    const std::string& key = tok[0];
    if (key == "solid" || key == "endsolid") {
      if (in_facet) throw fail(fmt::format("'{}' inside a facet", key));
    } else if (key == "facet") {
      if (in_facet) throw fail("'facet' before 'endfacet'");
      in_facet = true;
      corners = 0;
    } else if (key == "outer" || key == "endloop") {
      if (!in_facet) throw fail(fmt::format("'{}' outside a facet", key));
    } else if (key == "vertex") {
      if (!in_facet || corners == 3) throw fail("unexpected 'vertex'");
      if (tok.size() != 4) throw fail("vertex needs 3 coordinates");
      Eigen::Vector3d v;
      for (int d = 0; d < 3; ++d)
        if (!parse_finite(tok[d + 1], v[d])) throw fail("bad number " + quote_token(tok[d + 1]));
      mesh.vertices.push_back(v);
      ++corners;
    } else if (key == "endfacet") {
      if (!in_facet || corners != 3) throw fail("facet without exactly 3 vertices");
      const int base = static_cast<int>(mesh.vertices.size()) - 3;
      mesh.triangles.push_back({base, base + 1, base + 2});
      in_facet = false;
    } else {
      throw fail("unexpected keyword " + quote_token(key));
    }
  }
  if (in_facet) throw fail("file ends inside a facet");
  return mesh;
}

}  // namespace

Mesh read_obj(const std::string& path) {
  const std::string text = read_whole_file(path, "mesh file");
  ObjState st{path, {}, 0, 0};
  LineReader lines(text);
  std::string line;
  while (lines.next(line)) {
    const std::size_t hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    const auto tok = split_whitespace(line);
    if (tok.empty()) continue;
    if (tok[0] == "v") {
      obj_vertex(st, tok, lines.number());
    } else if (tok[0] == "f") {
      obj_face(st, tok, lines.number());
    }
    // vt, vn, g, o, s, usemtl, mtllib, l, ... carry nothing a solid needs.
  }
  if (st.max_index > static_cast<long>(st.mesh.vertices.size()))
    throw InputError(fmt::format("{}:{}: face index {} out of range (file has {} vertices)", path,
                                 st.max_index_line, st.max_index, st.mesh.vertices.size()));
  if (st.mesh.triangles.empty()) throw InputError(fmt::format("{}: no faces in OBJ", path));
  return std::move(st.mesh);
}

Mesh read_stl(const std::string& path) {
  const std::string bytes = read_whole_file(path, "mesh file");
  if (bytes.empty()) throw InputError(fmt::format("{}: empty STL file", path));
  Mesh mesh;
  bool binary = false;
  if (bytes.size() >= 84) {
    std::uint32_t count = 0;
    std::memcpy(&count, bytes.data() + 80, 4);
    // Binary headers often begin with "solid" too, so an exact size match decides first.
    binary = bytes.size() == 84 + 50 * static_cast<std::size_t>(count);
  }
  if (binary || (!looks_like_text(bytes) && bytes.size() >= 84)) {
    mesh = parse_binary_stl(path, bytes);
  } else if (looks_like_text(bytes)) {
    mesh = parse_ascii_stl(path, bytes);
  } else {
    throw InputError(
        fmt::format("{}: not an STL file ({} bytes, no 'solid' keyword)", path, bytes.size()));
  }
  if (mesh.triangles.empty()) throw InputError(fmt::format("{}: no triangles in STL", path));
  return mesh;
}

Mesh read_mesh(const std::string& path) {
  const std::size_t dot = path.find_last_of('.');
  const std::size_t slash = path.find_last_of('/');
  std::string ext;
  if (dot != std::string::npos && (slash == std::string::npos || dot > slash))
    ext = path.substr(dot);
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".obj") return read_obj(path);
  if (ext == ".stl") return read_stl(path);
  throw InputError(fmt::format("{}: unsupported mesh format {} (expected .obj or .stl)", path,
                               quote_token(ext)));
}

double signed_volume(const Mesh& mesh, const Eigen::Vector3d& apex) {
  double six_v = 0;
  for (const auto& t : mesh.triangles) {
    const Eigen::Vector3d a = mesh.vertices[t[0]] - apex, b = mesh.vertices[t[1]] - apex;
    six_v += a.dot(b.cross(mesh.vertices[t[2]] - apex));
  }
  return six_v / 6.0;
}

}  // namespace gen4d::geometry
