#include "gaussians/Ply.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <string_view>

#include "core/Error.hpp"
#include "io/AtomicFile.hpp"

namespace gen4d::gaussians {

namespace {

namespace fs = std::filesystem;

constexpr bool kLittleEndianHost = __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__;

//! A unit quaternion read back from float32 is off by at most ~6e-8 in norm; one within this
//! tolerance is kept as stored, so a written file reads back to exactly the values it holds.
constexpr double kUnitTolerance = 0x1p-22;

//! Opacity is kept inside (0, 1) so that its logit stays finite.
constexpr double kMinOpacity = std::numeric_limits<double>::min();
constexpr double kMaxOpacity = 1.0 - 0x1p-53;

struct Property {
  std::string name;
  std::string type;
  std::size_t size = 0;    //!< bytes in the binary body
  std::size_t offset = 0;  //!< byte offset in a binary row
};

struct Header {
  bool binary = true;
  std::size_t count = 0;
  std::vector<Property> props;
  std::size_t stride = 0;
  std::size_t body = 0;  //!< offset of the body in the file
};

std::size_t type_size(const std::string& t) {
  if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
  if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
  if (t == "int" || t == "uint" || t == "int32" || t == "uint32") return 4;
  if (t == "float" || t == "float32") return 4;
  if (t == "double" || t == "float64") return 8;
  return 0;
}

bool is_float32(const std::string& t) {
  return t == "float" || t == "float32";
}

std::vector<std::string_view> words(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    if (i > start) out.push_back(line.substr(start, i - start));
  }
  return out;
}

std::string read_file(const std::string& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) throw InputError(path + ": is a directory, not a PLY file");
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (file == nullptr)
    throw InputError(path + ": cannot open the splat PLY: " + std::strerror(errno));
  std::string bytes;
  char buffer[1 << 16];
  // One bulk read when the size is known, then whatever remains.
  if (std::fseek(file, 0, SEEK_END) == 0) {
    const long size = std::ftell(file);
    std::rewind(file);
    if (size > 0) {
      bytes.resize(static_cast<std::size_t>(size));
      bytes.resize(std::fread(bytes.data(), 1, bytes.size(), file));
    }
  }
  std::size_t got;
  while ((got = std::fread(buffer, 1, sizeof buffer, file)) > 0) bytes.append(buffer, got);
  const bool failed = std::ferror(file) != 0;
  std::fclose(file);
  if (failed) throw InputError(path + ": cannot read the splat PLY");
  return bytes;
}

Header parse_header(const std::string& path, const std::string& bytes) {
  Header h;
  std::size_t pos = 0;
  int line_no = 0;
  bool have_format = false, in_vertex = false, seen_vertex = false;
  for (;;) {
    const std::size_t end = bytes.find('\n', pos);
    if (end == std::string::npos) {
      if (line_no == 0) throw InputError(path + ": not a PLY file (no 'ply' line)");
      throw InputError(path + ": the PLY header has no end_header");
    }
    std::string_view line(bytes.data() + pos, end - pos);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    pos = end + 1;
    ++line_no;
    const std::string where = path + ": line " + std::to_string(line_no) + ": ";
    if (line_no == 1) {
      if (line != "ply") throw InputError(path + ": not a PLY file (the first line is not 'ply')");
      continue;
    }
    const std::vector<std::string_view> w = words(line);
    if (w.empty()) continue;
    if (w[0] == "comment" || w[0] == "obj_info") continue;
    if (w[0] == "end_header") break;
    if (w[0] == "format") {
      if (w.size() != 3 || w[2] != "1.0")
        throw InputError(where + "bad format line '" + std::string(line) + "'");
      if (w[1] == "binary_little_endian") {
        h.binary = true;
      } else if (w[1] == "ascii") {
        h.binary = false;
      } else {
        throw InputError(where + "format '" + std::string(w[1]) +
                         "' is not supported (binary_little_endian or ascii)");
      }
      have_format = true;
    } else if (w[0] == "element") {
      if (w.size() != 3) throw InputError(where + "bad element line '" + std::string(line) + "'");
      if (seen_vertex) {
        in_vertex = false;  // elements after the vertices are ignored
        continue;
      }
      if (w[1] != "vertex")
        throw InputError(where + "element '" + std::string(w[1]) +
                         "' before the vertex element is not supported");
      std::size_t count = 0;
      const auto [p, ec] = std::from_chars(w[2].data(), w[2].data() + w[2].size(), count);
      if (ec != std::errc() || p != w[2].data() + w[2].size())
        throw InputError(where + "bad vertex count '" + std::string(w[2]) + "'");
      h.count = count;
      seen_vertex = in_vertex = true;
    } else if (w[0] == "property") {
      if (!seen_vertex) throw InputError(where + "property before any element");
      if (!in_vertex) continue;
      if (w.size() >= 2 && w[1] == "list")
        throw InputError(where + "list property '" + std::string(w.back()) +
                         "' in the vertex element is not supported");
      if (w.size() != 3) throw InputError(where + "bad property line '" + std::string(line) + "'");
      Property prop{std::string(w[2]), std::string(w[1]), type_size(std::string(w[1])), 0};
      if (prop.size == 0)
        throw InputError(where + "property '" + prop.name + "' has unknown type '" + prop.type +
                         "'");
      for (const Property& other : h.props)
        if (other.name == prop.name)
          throw InputError(where + "property '" + prop.name + "' appears twice");
      prop.offset = h.stride;
      h.stride += prop.size;
      h.props.push_back(std::move(prop));
    } else {
      throw InputError(where + "unexpected header line '" + std::string(line) + "'");
    }
  }
  if (!have_format) throw InputError(path + ": the PLY header has no format line");
  if (!seen_vertex) throw InputError(path + ": the PLY header has no vertex element");
  h.body = pos;
  return h;
}

//! Where each value of a splat comes from: property index per slot.
struct Layout {
  int degree = 0;
  std::vector<int> slot;  //!< property index of slot s
  std::vector<std::string> slot_name;
};

// Slots: 0-2 x y z, 3-5 f_dc, 6 opacity, 7-9 scale, 10-13 rot, 14.. f_rest.
constexpr int kFixedSlots = 14;

Layout make_layout(const std::string& path, const Header& h) {
  std::map<std::string, int> index;
  for (std::size_t i = 0; i < h.props.size(); ++i) index[h.props[i].name] = static_cast<int>(i);
  Layout L;
  const char* fixed[kFixedSlots] = {"x",      "y",       "z",       "f_dc_0",  "f_dc_1",
                                    "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2",
                                    "rot_0",  "rot_1",   "rot_2",   "rot_3"};
  for (const char* name : fixed) L.slot_name.emplace_back(name);
  int rest = 0;
  for (const Property& p : h.props)
    if (p.name.rfind("f_rest_", 0) == 0) ++rest;
  if (rest != 0 && rest != 9 && rest != 24 && rest != 45)
    throw InputError(path + ": " + std::to_string(rest) +
                     " f_rest properties, expected 0, 9, 24 or 45 (SH degree 0..3)");
  L.degree = rest == 0 ? 0 : rest == 9 ? 1 : rest == 24 ? 2 : 3;
  for (int j = 0; j < rest; ++j) L.slot_name.push_back("f_rest_" + std::to_string(j));
  for (const std::string& name : L.slot_name) {
    const auto it = index.find(name);
    if (it == index.end()) throw InputError(path + ": missing vertex property '" + name + "'");
    const Property& p = h.props[it->second];
    if (!is_float32(p.type))
      throw InputError(path + ": vertex property '" + name + "' is " + p.type +
                       ", expected float (float32)");
    L.slot.push_back(it->second);
  }
  return L;
}

//! Fills `values` (slots x count, row-major by splat) from the body.
void read_body(const std::string& path, const std::string& bytes, const Header& h, const Layout& L,
               std::vector<float>& values) {
  const std::size_t slots = L.slot.size();
  const std::size_t available = bytes.size() - h.body;
  if (h.binary) {
    const std::size_t rows = h.stride == 0 ? 0 : available / h.stride;
    if (rows < h.count)
      throw InputError(path + ": vertex row " + std::to_string(rows) + " of " +
                       std::to_string(h.count) + " is truncated (the body holds " +
                       std::to_string(available) + " bytes)");
    values.resize(slots * h.count);
    std::vector<std::size_t> offset(slots);
    for (std::size_t s = 0; s < slots; ++s) offset[s] = h.props[L.slot[s]].offset;
    const char* body = bytes.data() + h.body;
    for (std::size_t i = 0; i < h.count; ++i) {
      const char* row = body + i * h.stride;
      float* out = &values[i * slots];
      for (std::size_t s = 0; s < slots; ++s) {
        std::uint32_t u;
        std::memcpy(&u, row + offset[s], 4);
        if (!kLittleEndianHost) u = __builtin_bswap32(u);
        std::memcpy(&out[s], &u, 4);
      }
    }
    return;
  }
  // ASCII: whitespace-separated tokens, props.size() per vertex. A row takes at least two bytes
  // per property, which bounds the rows a body can hold before it is parsed.
  values.resize(slots * std::min(h.count, (available + 1) / (2 * h.props.size())));
  std::vector<int> slot_of(h.props.size(), -1);
  for (std::size_t s = 0; s < slots; ++s) slot_of[L.slot[s]] = static_cast<int>(s);
  const char* p = bytes.data() + h.body;
  const char* end = bytes.data() + bytes.size();
  auto space = [](char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; };
  for (std::size_t i = 0; i < h.count; ++i) {
    // Only complete rows fit that bound: a last row cut short (reported below) may start past it.
    if (values.size() < (i + 1) * slots) values.resize((i + 1) * slots);
    for (std::size_t k = 0; k < h.props.size(); ++k) {
      while (p < end && space(*p)) ++p;
      if (p == end)
        throw InputError(path + ": vertex row " + std::to_string(i) + " of " +
                         std::to_string(h.count) + " is truncated (no value for property '" +
                         h.props[k].name + "')");
      const char* start = p;
      while (p < end && !space(*p)) ++p;
      const int s = slot_of[k];
      if (s < 0) continue;
      float v = 0;
      const auto [q, ec] = std::from_chars(start, p, v);
      if (ec != std::errc() || q != p)
        throw InputError(path + ": vertex row " + std::to_string(i) + ", property '" +
                         h.props[k].name + "': '" + std::string(start, p) +
                         "' is not a float32 number");
      values[i * slots + s] = v;
    }
  }
}

double sigmoid(double v) {
  const double o = v >= 0 ? 1.0 / (1.0 + std::exp(-v)) : std::exp(v) / (1.0 + std::exp(v));
  return std::clamp(o, kMinOpacity, kMaxOpacity);
}

void put_le(char* dst, float v) {
  std::uint32_t u;
  std::memcpy(&u, &v, 4);
  if (!kLittleEndianHost) u = __builtin_bswap32(u);
  std::memcpy(dst, &u, 4);
}

}  // namespace

SplatSet read_splats_ply(const std::string& path) {
  const std::string bytes = read_file(path);
  const Header h = parse_header(path, bytes);
  const Layout L = make_layout(path, h);
  std::vector<float> values;
  read_body(path, bytes, h, L, values);

  SplatSet s;
  s.sh_degree = L.degree;
  const std::size_t n = h.count, slots = L.slot.size();
  const int K = s.coefficients();
  s.position.resize(3 * n);
  s.scale.resize(3 * n);
  s.rotation.resize(4 * n);
  s.opacity.resize(n);
  s.sh.resize(3 * static_cast<std::size_t>(K) * n);
  for (std::size_t i = 0; i < n; ++i) {
    const float* v = &values[i * slots];
    for (std::size_t t = 0; t < slots; ++t)
      if (!std::isfinite(v[t]))
        throw InputError(path + ": vertex row " + std::to_string(i) + ", property '" +
                         L.slot_name[t] + "' is " + (std::isnan(v[t]) ? "nan" : "inf"));
    for (int d = 0; d < 3; ++d) s.position[3 * i + d] = v[d];
    double* sh = &s.sh[3 * K * i];
    for (int c = 0; c < 3; ++c) sh[c] = v[3 + c];
    for (int k = 1; k < K; ++k)
      for (int c = 0; c < 3; ++c) sh[3 * k + c] = v[kFixedSlots + (k - 1) + c * (K - 1)];
    s.opacity[i] = sigmoid(v[6]);
    for (int d = 0; d < 3; ++d) {
      const double e = std::exp(static_cast<double>(v[7 + d]));
      if (!(e > 0) || !std::isfinite(e))
        throw InputError(path + ": vertex row " + std::to_string(i) + ", property 'scale_" +
                         std::to_string(d) + "' = " + std::to_string(v[7 + d]) +
                         " is no log-scale (exp gives " + std::to_string(e) + ")");
      s.scale[3 * i + d] = e;
    }
    double q[4], norm2 = 0;
    for (int d = 0; d < 4; ++d) {
      q[d] = v[10 + d];
      norm2 += q[d] * q[d];
    }
    if (norm2 == 0)
      throw InputError(path + ": vertex row " + std::to_string(i) +
                       " has a zero quaternion (rot_0..rot_3)");
    const double norm = std::sqrt(norm2);
    const double scale = std::abs(norm - 1) > kUnitTolerance ? 1 / norm : 1;
    for (int d = 0; d < 4; ++d) s.rotation[4 * i + d] = q[d] * scale;
  }
  return s;
}

void write_splats_ply(const std::string& path, const SplatSet& splats) {
  splats.check_sizes();
  const std::size_t n = splats.size();
  const int K = splats.coefficients();
  std::string header =
      "ply\nformat binary_little_endian 1.0\nelement vertex " + std::to_string(n) + "\n";
  std::vector<std::string> names = {"x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"};
  for (int j = 0; j < 3 * (K - 1); ++j) names.push_back("f_rest_" + std::to_string(j));
  for (const char* name :
       {"opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"})
    names.emplace_back(name);
  for (const std::string& name : names) header += "property float " + name + "\n";
  header += "end_header\n";

  const std::size_t per = names.size();
  std::string bytes(header.size() + 4 * per * n, '\0');
  std::copy(header.begin(), header.end(), bytes.begin());
  std::vector<float> row(per);
  for (std::size_t i = 0; i < n; ++i) {
    const std::string splat = path + ": splat " + std::to_string(i) + ": ";
    const double o = splats.opacity[i];
    if (!(o > 0 && o < 1))
      throw RuntimeError(splat + "opacity " + std::to_string(o) + " is outside (0, 1)");
    std::size_t t = 0;
    for (int d = 0; d < 3; ++d) row[t++] = static_cast<float>(splats.position[3 * i + d]);
    for (int d = 0; d < 3; ++d) row[t++] = 0.0f;
    const double* sh = &splats.sh[3 * K * i];
    for (int c = 0; c < 3; ++c) row[t++] = static_cast<float>(sh[c]);
    for (int c = 0; c < 3; ++c)
      for (int k = 1; k < K; ++k) row[t++] = static_cast<float>(sh[3 * k + c]);
    row[t++] = static_cast<float>(std::log(o / (1 - o)));
    for (int d = 0; d < 3; ++d) {
      const double sc = splats.scale[3 * i + d];
      if (!(sc > 0)) throw RuntimeError(splat + "scale " + std::to_string(sc) + " is not positive");
      row[t++] = static_cast<float>(std::log(sc));
    }
    for (int d = 0; d < 4; ++d) row[t++] = static_cast<float>(splats.rotation[4 * i + d]);
    for (std::size_t k = 0; k < per; ++k) {
      if (!std::isfinite(row[k]))
        throw RuntimeError(splat + "property '" + names[k] + "' is not a finite float32");
      put_le(&bytes[header.size() + 4 * (per * i + k)], row[k]);
    }
  }

  io::write_atomically(path, std::string_view(bytes.data(), bytes.size()), true);
}

}  // namespace gen4d::gaussians
