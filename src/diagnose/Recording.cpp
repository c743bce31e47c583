#include "diagnose/Recording.hpp"

#include <fmt/format.h>
#include <hdf5.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iterator>
#include <map>
#include <string_view>
#include <unordered_map>
#include <utility>

#include "core/Error.hpp"
#include "io/Hdf5.hpp"

namespace gen4d::diagnose {
namespace {

namespace fs = std::filesystem;
namespace h5 = io::h5;

// Column roles: the id, the reference point X,Y,Z, the time and the three values.
enum Role { kId, kX, kY, kZ, kT, kV0, kV1, kV2, kRoles };
using Names = std::array<const char*, kRoles>;
using Values = std::array<double, kRoles>;  // indexed by Role; the kId slot is unused
using Measured = std::array<bool, 3>;       // per value role kV0..kV2

const Names& column_names(ChannelKind kind) {
  static const Names position{"marker", "X", "Y", "Z", "t", "x", "y", "z"};
  static const Names acceleration{"sensor", "X", "Y", "Z", "t", "ax", "ay", "az"};
  return kind == ChannelKind::Position ? position : acceleration;
}

//! Which value columns of `kind` opt.unmeasured names; InputError for a name that is no value
//! column.
Measured forced_unmeasured(ChannelKind kind, const ReadOptions& opt) {
  const Names& names = column_names(kind);
  const auto& all = value_column_names();
  Measured off{false, false, false};
  for (const std::string& n : opt.unmeasured) {
    if (std::find(all.begin(), all.end(), n) == all.end()) {
      std::string list;
      for (const auto& a : all) list += (list.empty() ? "" : ", ") + a;
      throw InputError(
          fmt::format("--unmeasured: '{}' is not a value column (one of {})", n, list));
    }
    for (int d = 0; d < 3; ++d) off[static_cast<std::size_t>(d)] |= n == names[kV0 + d];
  }
  return off;
}

std::string joined_names(const Names& names) {
  std::string s;
  for (const char* n : names) s += (s.empty() ? "" : ",") + std::string(n);
  return s;
}

bool is_space(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
  return s;
}

std::string lower_extension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

bool hdf5_extension(const std::string& path) {
  const std::string ext = lower_extension(path);
  return ext == ".h5" || ext == ".hdf5";
}

std::string point_text(const std::array<double, 3>& p) {
  return fmt::format("({}, {}, {})", p[0], p[1], p[2]);
}

//! Where rows come from, for messages: "file:line" (CSV) or "file: dataset D row R" (HDF5).
struct Where {
  std::string file;
  bool hdf5 = false;
  std::string group;  // HDF5 only: "" (root), "/positions" or "/accelerations"

  const char* unit() const { return hdf5 ? "row" : "line"; }
  std::string at(long line) const {
    if (!hdf5) return fmt::format("{}:{}", file, line);
    return group.empty() ? fmt::format("{}: row {}", file, line)
                         : fmt::format("{}: {} row {}", file, group, line);
  }
  std::string at(long line, std::string_view key) const {
    return hdf5 ? fmt::format("{}: dataset {}/{} row {}", file, group, key, line)
                : fmt::format("{}:{}: column '{}'", file, line, key);
  }
};

//! Collects the samples of one kind into channels (in order of first appearance), checking
//! each channel as its samples arrive.
class Builder {
 public:
  Builder(Where where, ChannelKind kind)
      : where_(std::move(where)), kind_(kind), names_(column_names(kind)) {}

  //! A sample; m: which of its values were measured (the others are ignored). A sample with
  //! none measured is skipped.
  void add(std::string_view id, const Values& v, const Measured& m, long line) {
    for (int r = kX; r < kRoles; ++r) {
      if (r >= kV0 && !m[static_cast<std::size_t>(r - kV0)]) continue;
      if (!std::isfinite(v[r])) {
        throw InputError(fmt::format("{}: value {} is not finite (NaN or inf)",
                                     where_.at(line, names_[r]), v[r]));
      }
    }
    if (!m[0] && !m[1] && !m[2]) {
      unmeasured_.emplace(std::string(id), line);  // keeps the first line
      return;
    }
    Channel& c = channel(id, v);
    const std::array<double, 3> X{v[kX], v[kY], v[kZ]};
    const double tol = 1e-12 * std::max(1.0, std::hypot(c.X[0], c.X[1], c.X[2]));
    for (int d = 0; d < 3; ++d) {
      if (std::abs(X[d] - c.X[d]) > tol) {
        throw InputError(
            fmt::format("{}: reference X,Y,Z of {} '{}' changes: {} here but {} at {} {}",
                        where_.at(line, names_[kX + d]), names_[kId], c.id, point_text(X),
                        point_text(c.X), where_.unit(), c.line.front()));
      }
    }
    const double t = v[kT];
    if (!c.t.empty() && !(t > c.t.back())) {
      throw InputError(fmt::format(
          "{}: time {} at {} {} for {} '{}': t={} after t={} ({} {})", where_.at(line, names_[kT]),
          t == c.t.back() ? "repeats" : "goes backwards", where_.unit(), line, names_[kId], c.id, t,
          c.t.back(), where_.unit(), c.line.back()));
    }
    c.t.push_back(t);
    c.value.push_back({m[0] ? v[kV0] : 0.0, m[1] ? v[kV1] : 0.0, m[2] ? v[kV2] : 0.0});
    c.measured.push_back(m);
    c.line.push_back(line);
  }

  //! The channels; throws when there are none, one has fewer than 2 samples or an id has no
  //! measured value. A channel whose every value is measured keeps an empty mask.
  std::vector<Channel> finish(const std::string& none_message) {
    for (const auto& [id, line] : unmeasured_) {
      if (index_.count(id) == 0) {
        throw InputError(
            fmt::format("{}: {} '{}' has no measured value (every value is empty "
                        "or not measured)",
                        where_.at(line), names_[kId], id));
      }
    }
    if (channels_.empty()) throw InputError(none_message);
    for (Channel& c : channels_) {
      if (c.t.size() < 2) {
        throw InputError(fmt::format("{}: {} '{}' has only {} sample; at least 2 are needed",
                                     where_.at(c.line.front()), names_[kId], c.id, c.t.size()));
      }
      const bool all = std::all_of(c.measured.begin(), c.measured.end(),
                                   [](const Measured& m) { return m[0] && m[1] && m[2]; });
      if (all) c.measured.clear();
    }
    return std::move(channels_);
  }

 private:
  Channel& channel(std::string_view id, const Values& v) {
    // Rows of one marker usually come together: try the previous row's channel first.
    if (last_ < channels_.size() && channels_[last_].id == id) return channels_[last_];
    std::string key(id);
    auto it = index_.find(key);
    if (it != index_.end()) {
      last_ = it->second;
      return channels_[last_];
    }
    last_ = channels_.size();
    index_.emplace(key, last_);
    Channel& c = channels_.emplace_back();
    c.id = std::move(key);
    c.kind = kind_;
    c.X = {v[kX], v[kY], v[kZ]};
    c.file = where_.file;
    return c;
  }

  Where where_;
  ChannelKind kind_;
  const Names& names_;
  std::vector<Channel> channels_;
  std::unordered_map<std::string, std::size_t> index_;
  std::map<std::string, long> unmeasured_;  //!< ids of samples with no measured value
  std::size_t last_ = static_cast<std::size_t>(-1);
};

// ---------------------------------------------------------------------------------------------
// CSV

//! The whole file; InputError naming the path when it is missing or unreadable.
std::string read_text(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError(path + ": no such file");
  if (fs::is_directory(path, ec)) throw InputError(path + ": is a directory, not a recording");
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) {
    throw InputError(fmt::format("{}: cannot open ({})", path, std::strerror(errno)));
  }
  std::string text;
  const auto size = fs::file_size(path, ec);
  if (!ec) text.reserve(static_cast<std::size_t>(size));
  char buffer[1 << 16];
  std::size_t n = 0;
  while ((n = std::fread(buffer, 1, sizeof buffer, f)) > 0) text.append(buffer, n);
  const bool failed = std::ferror(f) != 0;
  std::fclose(f);
  if (failed) throw InputError(path + ": read error");
  return text;
}

//! Splits a text into lines ('\n' or "\r\n"), counting from 1.
class Lines {
 public:
  explicit Lines(std::string_view text) : text_(text) {
    if (text_.substr(0, 3) == "\xEF\xBB\xBF") text_.remove_prefix(3);  // UTF-8 byte order mark
  }
  bool next(std::string_view& line) {
    if (pos_ >= text_.size()) return false;
    std::size_t end = text_.find('\n', pos_);
    if (end == std::string_view::npos) end = text_.size();
    line = text_.substr(pos_, end - pos_);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    pos_ = end + 1;
    ++number_;
    return true;
  }
  long number() const { return number_; }

 private:
  std::string_view text_;
  std::size_t pos_ = 0;
  long number_ = 0;
};

bool skipped(std::string_view line) {
  line = trim(line);
  return line.empty() || line.front() == '#';
}

void split(std::string_view line, std::vector<std::string_view>& fields) {
  fields.clear();
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = line.find(',', start);
    if (comma == std::string_view::npos) {
      fields.push_back(line.substr(start));
      return;
    }
    fields.push_back(line.substr(start, comma - start));
    start = comma + 1;
  }
}

//! The header: which role each column plays; InputError naming the file, line and column.
std::pair<ChannelKind, std::vector<int>> parse_header(const std::vector<std::string_view>& fields,
                                                      const std::string& file, long line) {
  bool has_marker = false, has_sensor = false;
  for (std::string_view f : fields) {
    has_marker |= trim(f) == "marker";
    has_sensor |= trim(f) == "sensor";
  }
  if (has_marker && has_sensor) {
    throw InputError(
        fmt::format("{}:{}: columns 'marker' and 'sensor' both present; a CSV file holds one kind",
                    file, line));
  }
  if (!has_marker && !has_sensor) {
    throw InputError(
        fmt::format("{}:{}: missing column 'marker' (positions: {}; accelerometers: {})", file,
                    line, joined_names(column_names(ChannelKind::Position)),
                    joined_names(column_names(ChannelKind::Acceleration))));
  }
  const ChannelKind kind = has_marker ? ChannelKind::Position : ChannelKind::Acceleration;
  const Names& names = column_names(kind);
  std::vector<int> role(fields.size(), -1);
  std::array<bool, kRoles> seen{};
  for (std::size_t i = 0; i < fields.size(); ++i) {
    const std::string_view name = trim(fields[i]);
    const auto found =
        std::find_if(names.begin(), names.end(), [&](const char* n) { return name == n; });
    if (found == names.end()) {
      throw InputError(fmt::format("{}:{}: unknown column '{}' (expected the columns {})", file,
                                   line, name, joined_names(names)));
    }
    const int r = static_cast<int>(found - names.begin());
    if (seen[r]) throw InputError(fmt::format("{}:{}: duplicate column '{}'", file, line, name));
    seen[r] = true;
    role[i] = r;
  }
  for (int r = 0; r < kV0; ++r) {
    if (!seen[r]) {
      throw InputError(fmt::format("{}:{}: missing column '{}' (expected the columns {})", file,
                                   line, names[r], joined_names(names)));
    }
  }
  if (!seen[kV0] && !seen[kV1] && !seen[kV2]) {
    throw InputError(fmt::format("{}:{}: no value column: at least one of {}, {}, {} is needed",
                                 file, line, names[kV0], names[kV1], names[kV2]));
  }
  return {kind, role};
}

Recording read_csv(const std::string& path, const ReadOptions& opt) {
  const std::string text = read_text(path);
  Lines lines(text);
  std::string_view line;
  std::vector<std::string_view> fields;
  bool header = false;
  while (lines.next(line)) {
    if (!skipped(line)) {
      header = true;
      break;
    }
  }
  if (!header) throw InputError(path + ": empty file: no header and no data rows");
  const long header_line = lines.number();
  split(line, fields);
  const auto [kind, role] = parse_header(fields, path, header_line);
  const Names& names = column_names(kind);
  const std::size_t columns = role.size();

  // Value columns the header leaves out, or the options name, are never measured.
  const Measured off = forced_unmeasured(kind, opt);
  Measured present{false, false, false};
  for (int r : role)
    if (r >= kV0) present[static_cast<std::size_t>(r - kV0)] = true;
  Measured column_on{};
  for (std::size_t d = 0; d < 3; ++d) column_on[d] = present[d] && !off[d];

  Builder builder(Where{path, false, ""}, kind);
  Values v{};
  Measured m{};
  while (lines.next(line)) {
    if (skipped(line)) continue;
    const long n = lines.number();
    split(line, fields);
    if (fields.size() != columns) {
      throw InputError(
          fmt::format("{}:{}: expected {} fields, got {}", path, n, columns, fields.size()));
    }
    std::string_view id;
    m = column_on;
    for (std::size_t i = 0; i < columns; ++i) {
      const std::string_view field = trim(fields[i]);
      const int r = role[i];
      if (r == kId) {
        if (field.empty()) {
          throw InputError(fmt::format("{}:{}: column '{}': empty id", path, n, names[kId]));
        }
        id = field;
        continue;
      }
      if (r >= kV0) {  // a value: empty (not measured) or ignored when not measured
        const auto d = static_cast<std::size_t>(r - kV0);
        if (field.empty()) m[d] = false;
        if (!m[d]) {
          v[r] = 0.0;
          continue;
        }
      }
      // The text is NUL-terminated and a number cannot run past the separator that ends
      // `field`, so strtod stops inside the field or right at its end.
      char* end = nullptr;
      const double x = field.empty() ? 0.0 : std::strtod(field.data(), &end);
      if (field.empty() || end != field.data() + field.size()) {
        throw InputError(
            fmt::format("{}:{}: column '{}': '{}' is not a number", path, n, names[r], field));
      }
      v[r] = x;
    }
    builder.add(id, v, m, n);
  }
  Recording rec;
  rec.source = path;
  rec.channels =
      builder.finish(fmt::format("{}:{}: no data rows after the header", path, header_line));
  return rec;
}

// ---------------------------------------------------------------------------------------------
// HDF5

//! Opens the 1-D dataset `name` of `loc` (shown as `shown`) and returns its length in `n`.
h5::Handle open_1d(hid_t loc, const std::string& name, const std::string& shown,
                   const std::string& file, hsize_t& n) {
  if (!h5::link_exists(loc, name)) throw InputError(file + ": missing dataset " + shown);
  h5::Handle ds = h5::checked(H5Dopen2(loc, name.c_str(), H5P_DEFAULT), H5Dclose,
                              h5::Failure::Input, file + ": " + shown + " is not a dataset");
  h5::Handle space = h5::checked(H5Dget_space(ds.get()), H5Sclose, h5::Failure::Input,
                                 file + ": cannot read the shape of dataset " + shown);
  const int rank = H5Sget_simple_extent_ndims(space.get());
  if (rank != 1) {
    throw InputError(
        fmt::format("{}: dataset {} has rank {}, expected a 1-D dataset", file, shown, rank));
  }
  H5Sget_simple_extent_dims(space.get(), &n, nullptr);
  return ds;
}

std::vector<double> read_numbers(hid_t ds, hsize_t n, const std::string& shown,
                                 const std::string& file) {
  h5::Handle type = h5::checked(H5Dget_type(ds), H5Tclose, h5::Failure::Input,
                                file + ": cannot read the type of dataset " + shown);
  const H5T_class_t cls = H5Tget_class(type.get());
  if (cls != H5T_FLOAT && cls != H5T_INTEGER) {
    throw InputError(file + ": dataset " + shown + " is not numeric (expected float64)");
  }
  std::vector<double> v(n);
  if (n > 0) h5::read_all(ds, H5T_NATIVE_DOUBLE, v.data(), file + ": cannot read dataset " + shown);
  return v;
}

//! Integer ids (written as decimal text) or strings (fixed or variable length, trimmed).
std::vector<std::string> read_ids(hid_t ds, hsize_t n, const std::string& shown,
                                  const std::string& file) {
  const std::string what = file + ": cannot read dataset " + shown;
  h5::Handle type = h5::checked(H5Dget_type(ds), H5Tclose, h5::Failure::Input, what);
  const H5T_class_t cls = H5Tget_class(type.get());
  std::vector<std::string> ids(n);
  if (n == 0) return ids;
  if (cls == H5T_INTEGER) {
    std::vector<long long> v(n);
    h5::read_all(ds, H5T_NATIVE_LLONG, v.data(), what);
    for (hsize_t i = 0; i < n; ++i) ids[i] = std::to_string(v[i]);
    return ids;
  }
  if (cls != H5T_STRING) {
    throw InputError(file + ": dataset " + shown + " must hold integer or string ids");
  }
  h5::Handle mem = h5::checked(H5Tcopy(H5T_C_S1), H5Tclose, h5::Failure::Input, what);
  H5Tset_cset(mem.get(), H5Tget_cset(type.get()));
  if (H5Tis_variable_str(type.get()) > 0) {
    h5::check(H5Tset_size(mem.get(), H5T_VARIABLE), h5::Failure::Input, what);
    std::vector<char*> p(n, nullptr);
    h5::read_all(ds, mem.get(), p.data(), what);
    for (hsize_t i = 0; i < n; ++i) {
      if (p[i] != nullptr) ids[i] = std::string(trim(p[i]));
    }
    h5::Handle space = h5::checked(H5Dget_space(ds), H5Sclose, h5::Failure::Input, what);
    H5Dvlen_reclaim(mem.get(), space.get(), H5P_DEFAULT, p.data());
    return ids;
  }
  const std::size_t size = H5Tget_size(type.get()) + 1;  // room for the terminating NUL
  h5::check(H5Tset_size(mem.get(), size), h5::Failure::Input, what);
  h5::check(H5Tset_strpad(mem.get(), H5T_STR_NULLTERM), h5::Failure::Input, what);
  std::vector<char> buffer(n * size, '\0');
  h5::read_all(ds, mem.get(), buffer.data(), what);
  for (hsize_t i = 0; i < n; ++i) {
    const char* s = buffer.data() + i * size;
    ids[i] = std::string(trim(std::string_view(s, strnlen(s, size))));
  }
  return ids;
}

//! Reads the datasets of one kind from `loc` (the root or a group named `group`).
void read_hdf5_kind(hid_t loc, const std::string& file, const std::string& group, ChannelKind kind,
                    const Measured& off, std::vector<Channel>& out) {
  const Names& names = column_names(kind);
  auto shown = [&](int r) { return group + "/" + names[r]; };
  hsize_t rows = 0;
  h5::Handle id_ds = open_1d(loc, names[kId], shown(kId), file, rows);
  std::array<std::vector<double>, kRoles> columns;
  Measured present{false, false, false};
  for (int r = kX; r < kRoles; ++r) {
    if (r >= kV0 && !h5::link_exists(loc, names[r])) continue;  // a value not measured
    if (r >= kV0) present[static_cast<std::size_t>(r - kV0)] = true;
    hsize_t n = 0;
    h5::Handle ds = open_1d(loc, names[r], shown(r), file, n);
    if (n != rows) {
      throw InputError(fmt::format("{}: length mismatch: dataset {} has {} rows but {} has {}",
                                   file, shown(r), n, shown(kId), rows));
    }
    columns[r] = read_numbers(ds.get(), n, shown(r), file);
  }
  if (!present[0] && !present[1] && !present[2]) {
    throw InputError(fmt::format("{}: missing datasets {}, {}, {}: at least one value is needed",
                                 file, shown(kV0), shown(kV1), shown(kV2)));
  }
  const std::vector<std::string> ids = read_ids(id_ds.get(), rows, shown(kId), file);

  Builder builder(Where{file, true, group}, kind);
  Values v{};
  Measured m{};
  for (hsize_t i = 0; i < rows; ++i) {
    const long row = static_cast<long>(i);
    if (ids[i].empty()) {
      throw InputError(fmt::format("{}: dataset {} row {}: empty id", file, shown(kId), row));
    }
    for (int r = kX; r < kRoles; ++r) {
      if (r < kV0) {
        v[r] = columns[r][i];
        continue;
      }
      // NaN: not measured.
      const auto d = static_cast<std::size_t>(r - kV0);
      m[d] = present[d] && !off[d] && !std::isnan(columns[r][i]);
      v[r] = m[d] ? columns[r][i] : 0.0;
    }
    builder.add(ids[i], v, m, row);
  }
  for (Channel& c :
       builder.finish(fmt::format("{}: dataset {} is empty: no samples", file, shown(kId)))) {
    out.push_back(std::move(c));
  }
}

Recording read_hdf5(const std::string& path, const ReadOptions& opt) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError(path + ": no such file");
  h5::Handle file = h5::open_file_serial(path);
  Recording rec;
  rec.source = path;
  const bool positions = h5::link_exists(file.get(), "positions");
  const bool accelerations = h5::link_exists(file.get(), "accelerations");
  if (positions || accelerations) {
    for (auto [name, kind] : {std::pair{"positions", ChannelKind::Position},
                              std::pair{"accelerations", ChannelKind::Acceleration}}) {
      if (!h5::link_exists(file.get(), name)) continue;
      h5::Handle group = h5::open_group(file.get(), name, h5::Failure::Input, path);
      read_hdf5_kind(group.get(), path, std::string("/") + name, kind, forced_unmeasured(kind, opt),
                     rec.channels);
    }
    return rec;
  }
  const bool marker = h5::link_exists(file.get(), "marker");
  const bool sensor = h5::link_exists(file.get(), "sensor");
  if (marker && sensor) {
    throw InputError(path +
                     ": datasets /marker and /sensor both at the root; put both kinds in the "
                     "groups /positions and /accelerations");
  }
  if (!marker && !sensor) {
    throw InputError(path +
                     ": missing dataset /marker (or /sensor, or the groups /positions and "
                     "/accelerations)");
  }
  const ChannelKind kind = marker ? ChannelKind::Position : ChannelKind::Acceleration;
  read_hdf5_kind(file.get(), path, "", kind, forced_unmeasured(kind, opt), rec.channels);
  return rec;
}

bool has_hdf5_signature(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) return false;
  char head[8] = {};
  const std::size_t n = std::fread(head, 1, sizeof head, f);
  std::fclose(f);
  return n == 8 && std::memcmp(head, "\x89HDF\r\n\x1a\n", 8) == 0;
}

// ---------------------------------------------------------------------------------------------
// Writing

void write_atomically(const std::string& path, const fmt::memory_buffer& text) {
  const std::string tmp = fmt::format("{}.tmp{}", path, static_cast<long>(::getpid()));
  std::FILE* f = std::fopen(tmp.c_str(), "wb");
  if (f == nullptr) {
    throw RuntimeError(fmt::format("{}: cannot create ({})", tmp, std::strerror(errno)));
  }
  const bool written = std::fwrite(text.data(), 1, text.size(), f) == text.size();
  const bool closed = std::fclose(f) == 0;
  std::error_code ec;
  if (!written || !closed) {
    fs::remove(tmp, ec);
    throw RuntimeError(path + ": write failed");
  }
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw RuntimeError(fmt::format("{}: cannot rename the temporary file into place", path));
  }
}

void write_kind(const Recording& rec, ChannelKind kind, const std::string& path) {
  const Names& names = column_names(kind);
  fmt::memory_buffer out;
  fmt::format_to(std::back_inserter(out), "{}\n", joined_names(names));
  for (const Channel& c : rec.channels) {
    if (c.kind != kind) continue;
    if (c.id.empty() || c.id.find_first_of(",\n\r") != std::string::npos || trim(c.id) != c.id ||
        c.id.front() == '#') {
      throw RuntimeError(
          fmt::format("{}: {} id '{}' cannot be written to CSV", path, names[kId], c.id));
    }
    if (c.value.size() != c.t.size() || (!c.measured.empty() && c.measured.size() != c.t.size())) {
      throw RuntimeError(fmt::format("{}: {} '{}' has {} times but {} values ({} masks)", path,
                                     names[kId], c.id, c.t.size(), c.value.size(),
                                     c.measured.size()));
    }
    for (std::size_t i = 0; i < c.t.size(); ++i) {
      if (!c.has(i, 0) && !c.has(i, 1) && !c.has(i, 2)) continue;
      fmt::format_to(std::back_inserter(out), "{},{},{},{},{}", c.id, c.X[0], c.X[1], c.X[2],
                     c.t[i]);
      for (int d = 0; d < 3; ++d) {
        if (c.has(i, d))
          fmt::format_to(std::back_inserter(out), ",{}", c.value[i][static_cast<std::size_t>(d)]);
        else
          out.push_back(',');
      }
      out.push_back('\n');
    }
  }
  write_atomically(path, out);
}

//! The earliest of the channels' first sample times (last: the latest of their last ones); 0
//! without samples.
double time_bound(const std::vector<Channel>& channels, bool last) {
  double t = 0;
  bool first = true;
  for (const Channel& c : channels) {
    if (c.t.empty()) continue;
    const double ct = last ? c.t.back() : c.t.front();
    t = first ? ct : last ? std::max(t, ct) : std::min(t, ct);
    first = false;
  }
  return t;
}

}  // namespace

std::size_t Recording::samples() const {
  std::size_t n = 0;
  for (const Channel& c : channels) n += c.t.size();
  return n;
}

double Recording::t_begin() const {
  return time_bound(channels, false);
}

double Recording::t_end() const {
  return time_bound(channels, true);
}

const char* id_column(ChannelKind kind) {
  return column_names(kind)[kId];
}

const std::vector<std::string>& value_column_names() {
  static const std::vector<std::string> names{"x", "y", "z", "ax", "ay", "az"};
  return names;
}

Recording read_recording(const std::string& path, const ReadOptions& opt) {
  // Every name is checked, whichever kind the file holds.
  forced_unmeasured(ChannelKind::Position, opt);
  const std::string ext = lower_extension(path);
  if (ext == ".csv") return read_csv(path, opt);
  if (ext == ".h5" || ext == ".hdf5") return read_hdf5(path, opt);
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError(path + ": no such file");
  return has_hdf5_signature(path) ? read_hdf5(path, opt) : read_csv(path, opt);
}

void merge_recordings(Recording& into, Recording&& more) {
  for (Channel& c : into.channels) {
    if (c.file.empty()) c.file = into.source;
  }
  for (Channel& c : more.channels) {
    if (c.file.empty()) c.file = more.source;
  }
  // Check everything first so that a failed merge leaves `into` as it was.
  for (const Channel& c : more.channels) {
    for (const Channel& d : into.channels) {
      if (c.kind == d.kind && c.id == d.id) {
        throw InputError(
            fmt::format("{}: {} '{}' is already in {}", c.file, id_column(c.kind), c.id, d.file));
      }
    }
  }
  for (Channel& c : more.channels) into.channels.push_back(std::move(c));
  if (!more.source.empty()) {
    into.source = into.source.empty() ? more.source : into.source + ", " + more.source;
  }
  more.channels.clear();
}

void check_attached(const Recording& rec,
                    const std::function<bool(const std::array<double, 3>&)>& inside) {
  for (const Channel& c : rec.channels) {
    if (inside(c.X)) continue;
    const std::string& file = c.file.empty() ? rec.source : c.file;
    const long line = c.line.empty() ? 0 : c.line.front();
    const std::string at = hdf5_extension(file) ? fmt::format("{}: row {}", file, line)
                                                : fmt::format("{}:{}", file, line);
    throw InputError(fmt::format("{}: {} '{}' reference point {} is not inside the body", at,
                                 id_column(c.kind), c.id, point_text(c.X)));
  }
}

std::string acceleration_csv_path(const std::string& path) {
  const fs::path p(path);
  return (p.parent_path() / (p.stem().string() + "-acc" + p.extension().string())).string();
}

void write_recording_csv(const Recording& rec, const std::string& path) {
  bool positions = false, accelerations = false;
  for (const Channel& c : rec.channels) {
    (c.kind == ChannelKind::Position ? positions : accelerations) = true;
  }
  if (!positions && !accelerations) throw RuntimeError(path + ": the recording has no channels");
  if (positions) write_kind(rec, ChannelKind::Position, path);
  if (accelerations) write_kind(rec, ChannelKind::Acceleration, acceleration_csv_path(path));
}

}  // namespace gen4d::diagnose
