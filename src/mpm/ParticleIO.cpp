// MPM particle files: checkpoints and frames in id-block layout (HDF5, collective), PLY and
// OpenVDB point clouds gathered to rank 0, and a depth-shaded PNG reduced to rank 0.
#include "mpm/ParticleIO.hpp"

#include <fmt/format.h>
#include <openvdb/openvdb.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <numeric>
#include <sstream>

#include "core/Error.hpp"
#include "core/Log.hpp"
#include "io/AtomicFile.hpp"
#include "io/BytePack.hpp"
#include "io/Checkpoint.hpp"
#include "io/FrameLayout.hpp"
#include "io/PngPreview.hpp"
#include "io/Xdmf.hpp"
#include "parallel/Comm.hpp"
#include "parallel/Distribute.hpp"

namespace gen4d::mpm {
namespace fs = std::filesystem;
namespace h5 = io::h5;

namespace {

//! Ids are carried as doubles in the exchanged rows: exact below 2^53.
constexpr std::int64_t kMaxParticles = std::int64_t(1) << 53;

//! Throws E on every rank with the first failing rank's message ("" everywhere: no throw).
template <class E>
void throw_if_any(MPI_Comm comm, const std::string& local_error) {
  const std::string error = h5::first_error(comm, local_error);
  if (!error.empty()) throw E(error);
}

//! Why the arrays of `p` disagree in length; "" when they are consistent.
std::string inconsistent(const Particles& p) {
  return p.inconsistency();
}

// ---- rows exchanged between ranks: `width` doubles, column 0 the particle id ----------------

//! Sends row i of `rows` to rank owner[i] (collective, parallel::RowExchange); returns the rows
//! this rank holds afterwards, sorted by id (ties keep the exchange's order).
std::vector<double> exchange_rows(MPI_Comm comm, int width, std::vector<double> rows,
                                  const std::vector<int>& owner, const std::string& where) {
  parallel::RowExchange ex;
  ex.add(rows, width);
  try {
    ex.exchange(comm, owner);
  } catch (const RuntimeError& e) {
    throw RuntimeError(where + e.what());
  }
  const std::size_t m = rows.size() / width;
  std::vector<std::size_t> order(m);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return rows[a * width] < rows[b * width]; });
  std::vector<double> sorted(rows.size());
  for (std::size_t k = 0; k < m; ++k)
    std::copy_n(&rows[order[k] * width], width, &sorted[k * width]);
  return sorted;
}

//! This rank's id block with the particles' rows placed at their ids (zeros elsewhere).
struct DenseBlock {
  IdBlock block;
  int width = 0;
  std::vector<double> rows;
  std::vector<std::uint8_t> alive;
};

//! Routes `rows` (one per particle) to the ranks owning their id blocks. Ids outside
//! 0..total-1 or held twice are RuntimeErrors on every rank.
DenseBlock to_blocks(MPI_Comm comm, std::int64_t total, int width, const std::vector<double>& rows,
                     const std::string& where) {
  const int rank = parallel::rank(comm), size = parallel::size(comm);
  const std::size_t n = rows.size() / width;
  std::vector<int> owner(n, 0);
  std::string error;
  for (std::size_t i = 0; i < n && error.empty(); ++i) {
    const double id = rows[i * width];
    if (!(id >= 0 && id < static_cast<double>(total))) {
      error = where + fmt::format("particle id {} is outside 0..{}", id, total - 1);
    } else {
      owner[i] = id_block_owner(static_cast<std::int64_t>(id), total, size);
    }
  }
  throw_if_any<RuntimeError>(comm, error);
  const std::vector<double> sorted = exchange_rows(comm, width, rows, owner, where);
  DenseBlock dense;
  dense.block = id_block(total, rank, size);
  dense.width = width;
  dense.rows.assign(static_cast<std::size_t>(dense.block.count) * width, 0.0);
  dense.alive.assign(static_cast<std::size_t>(dense.block.count), 0);
  for (std::size_t k = 0; k < sorted.size() / width; ++k) {
    const auto id = static_cast<std::int64_t>(sorted[k * width]);
    const auto local = static_cast<std::size_t>(id - dense.block.begin);
    if (dense.alive[local]) {
      error = where + fmt::format("particle id {} is held twice", id);
      break;
    }
    dense.alive[local] = 1;
    std::copy_n(&sorted[k * width], width, &dense.rows[local * width]);
  }
  throw_if_any<RuntimeError>(comm, error);
  return dense;
}

//! Columns [offset, offset + width) of every dense row, as a [count][width] buffer.
std::vector<double> column(const DenseBlock& b, int offset, int width) {
  const std::size_t count = b.alive.size();
  std::vector<double> out(count * width);
  for (std::size_t i = 0; i < count; ++i)
    std::copy_n(&b.rows[i * b.width + offset], width, &out[i * width]);
  return out;
}

//! Rows of every particle to rank 0, sorted by id.
std::vector<double> gather_rows(MPI_Comm comm, int width, const std::vector<double>& rows,
                                const std::string& where) {
  return exchange_rows(comm, width, rows, std::vector<int>(rows.size() / width, 0), where);
}

// ---- checkpoint layout -------------------------------------------------------------------

//! One id-indexed dataset of a checkpoint: columns [offset, offset + width) of a row.
struct Column {
  const char* name;
  int offset;
  int width;
  bool byte;       //!< stored as uint8
  long since = 1;  //!< format_version that added it; older files read it as 0
};

//! A checkpoint row starts with Particles::pack's record.
constexpr int kCheckpointRow = Particles::kRecord;
const Column kCheckpointColumns[] = {{"position", 1, 3, false},
                                     {"velocity", 4, 3, false},
                                     {"C", 7, 9, false},
                                     {"F", 16, 9, false},
                                     {"state", 25, kStateSize, false},
                                     {"mass", 25 + kStateSize, 1, false},
                                     {"volume0", 26 + kStateSize, 1, false},
                                     {"flag", 27 + kStateSize, 1, true},
                                     {"material", 28 + kStateSize, 1, true, 2}};

//! The extra values of a row follow the kCheckpointRow fixed ones.
std::vector<double> checkpoint_rows(const Particles& p) {
  const int W = kCheckpointRow + p.extra_width;
  std::vector<double> rows(p.size() * W);
  for (std::size_t i = 0; i < p.size(); ++i) {
    double* r = &rows[i * W];
    p.pack(i, r);
    std::copy_n(p.extra.data() + i * p.extra_width, p.extra_width, r + kCheckpointRow);
  }
  return rows;
}

void write_checkpoint_contents(hid_t file, const ParticleCheckpointState& s,
                               const DenseBlock& dense) {
  h5::write_attr(file, "format", std::string(kParticleCheckpointFormat));
  h5::write_attr(file, "format_version", kParticleCheckpointFormatVersion);
  io::write_run_clock(file, s);
  h5::write_attr(file, "particle_count", static_cast<long>(s.total_particles));
  h5::write_string_list_attr(file, "state_names", s.state_names);
  if (!s.extra_names.empty()) h5::write_string_list_attr(file, "extra_names", s.extra_names);
  const auto rows = static_cast<hsize_t>(s.total_particles);
  const auto begin = static_cast<hsize_t>(dense.block.begin);
  const auto count = static_cast<hsize_t>(dense.block.count);
  for (const Column& c : kCheckpointColumns) {
    const std::vector<double> values = column(dense, c.offset, c.width);
    if (c.byte) {
      std::vector<std::uint8_t> bytes(values.begin(), values.end());
      h5::Handle dataset = h5::create_rows_dataset(file, c.name, H5T_STD_U8LE, rows, c.width);
      h5::write_rows(dataset.get(), H5T_NATIVE_UINT8, begin, count, c.width, bytes.data());
    } else {
      h5::Handle dataset = h5::create_rows_dataset(file, c.name, H5T_IEEE_F64LE, rows, c.width);
      h5::write_rows(dataset.get(), H5T_NATIVE_DOUBLE, begin, count, c.width, values.data());
    }
  }
  h5::Handle alive = h5::create_rows_dataset(file, "alive", H5T_STD_U8LE, rows, 1);
  h5::write_rows(alive.get(), H5T_NATIVE_UINT8, begin, count, 1, dense.alive.data());
  const int extra = static_cast<int>(s.extra_names.size());
  if (extra > 0) {
    const std::vector<double> values = column(dense, kCheckpointRow, extra);
    h5::Handle dataset = h5::create_rows_dataset(file, "extra", H5T_IEEE_F64LE, rows, extra);
    h5::write_rows(dataset.get(), H5T_NATIVE_DOUBLE, begin, count, extra, values.data());
  }
}

//! The names of the extra columns (none in a file without the attribute).
std::vector<std::string> read_extra_names(hid_t file, const std::string& path) {
  if (!h5::has_attr(file, "extra_names")) return {};
  return h5::read_string_list_attr(file, "extra_names", path);
}

//! Checks the format attributes and every dataset's shape and type; returns N.
std::int64_t check_checkpoint_layout(hid_t file, const std::string& path) {
  const long version = h5::check_format(file, path, "MPM checkpoint", kParticleCheckpointFormat, 1,
                                        kParticleCheckpointFormatVersion);
  const long total = h5::read_long_attr(file, "particle_count", path);
  if (total < 0 || total > kMaxParticles) {
    throw InputError(path + ": particle_count " + std::to_string(total) + " is out of range");
  }
  const auto rows = static_cast<hsize_t>(total);
  for (const Column& c : kCheckpointColumns) {
    if (c.since > version) continue;
    h5::open_rows_dataset(file, std::string("/") + c.name, c.byte ? H5T_INTEGER : H5T_FLOAT, rows,
                          c.width, path);
  }
  h5::open_rows_dataset(file, "/alive", H5T_INTEGER, rows, 1, path);
  const std::size_t extra = read_extra_names(file, path).size();
  if (extra > 0)
    h5::open_rows_dataset(file, "/extra", H5T_FLOAT, rows, static_cast<hsize_t>(extra), path);
  return total;
}

ParticleCheckpointMeta read_meta_serial(const std::string& path) {
  h5::Handle file = h5::open_file_serial(path);
  ParticleCheckpointMeta meta;
  meta.total_particles = check_checkpoint_layout(file.get(), path);
  static_cast<io::RunClock&>(meta) = io::read_run_clock(file.get(), path);
  meta.state_names = h5::read_string_list_attr(file.get(), "state_names", path);
  if (meta.state_names.size() > static_cast<std::size_t>(kStateSize)) {
    throw InputError(path + fmt::format(": {} state_names, at most {} are supported",
                                        meta.state_names.size(), kStateSize));
  }
  meta.extra_names = read_extra_names(file.get(), path);
  return meta;
}

// Byte packing of ParticleCheckpointMeta for the broadcast from rank 0.
std::string pack(const ParticleCheckpointMeta& m) {
  std::string buffer;
  io::pack_run_clock(buffer, m);
  io::bytes::put(buffer, m.total_particles);
  for (const auto* names : {&m.state_names, &m.extra_names}) {
    io::bytes::put(buffer, names->size());
    for (const std::string& name : *names) io::bytes::put(buffer, name);
  }
  return buffer;
}

ParticleCheckpointMeta unpack(const std::string& buffer) {
  ParticleCheckpointMeta m;
  io::bytes::Unpacker in{buffer};
  io::unpack_run_clock(in, m);
  in.get(m.total_particles);
  for (auto* names : {&m.state_names, &m.extra_names}) {
    std::size_t count = 0;
    in.get(count);
    names->resize(count);
    for (std::string& name : *names) in.get(name);
  }
  return m;
}

//! Reads this rank's block of every dataset (collective) and keeps the alive particles, sorted
//! by id, with `extra` extra values each. InputError for a non-finite value of an alive
//! particle, after every read.
Particles read_block(hid_t file, const std::string& path, std::int64_t total, const IdBlock& b,
                     int extra) {
  const auto rows = static_cast<hsize_t>(total);
  const auto begin = static_cast<hsize_t>(b.begin);
  const auto count = static_cast<std::size_t>(b.count);
  std::vector<std::uint8_t> alive(count);
  {
    h5::Handle dataset = h5::open_rows_dataset(file, "/alive", H5T_INTEGER, rows, 1, path);
    h5::read_rows(dataset.get(), H5T_NATIVE_UINT8, begin, count, 1, alive.data(),
                  path + ": cannot read dataset /alive");
  }
  std::vector<double> dense(count * kCheckpointRow, 0.0);
  // Reported after the last read: every rank must join every collective read.
  std::string bad_value;
  const long version = h5::read_long_attr(file, "format_version", path);
  for (const Column& c : kCheckpointColumns) {
    if (c.since > version) continue;  // an older file: the column stays 0
    const std::string name = std::string("/") + c.name;
    h5::Handle dataset =
        h5::open_rows_dataset(file, name, c.byte ? H5T_INTEGER : H5T_FLOAT, rows, c.width, path);
    const std::string what = path + ": cannot read dataset " + name;
    std::vector<double> values(count * c.width);
    if (c.byte) {
      std::vector<std::uint8_t> bytes(count);
      h5::read_rows(dataset.get(), H5T_NATIVE_UINT8, begin, count, 1, bytes.data(), what);
      std::copy(bytes.begin(), bytes.end(), values.begin());
    } else {
      h5::read_rows(dataset.get(), H5T_NATIVE_DOUBLE, begin, count, c.width, values.data(), what);
      for (std::size_t i = 0; i < count; ++i) {
        for (int k = 0; k < c.width; ++k) {
          if (alive[i] && !std::isfinite(values[i * c.width + k]) && bad_value.empty()) {
            bad_value = path + fmt::format(
                                   ": dataset {} holds a non-finite value ({}) for "
                                   "alive particle id {}",
                                   name, values[i * c.width + k], b.begin + i);
          }
        }
      }
    }
    for (std::size_t i = 0; i < count; ++i)
      std::copy_n(&values[i * c.width], c.width, &dense[i * kCheckpointRow + c.offset]);
  }
  std::vector<double> extra_values(count * static_cast<std::size_t>(extra));
  if (extra > 0) {
    h5::Handle dataset =
        h5::open_rows_dataset(file, "/extra", H5T_FLOAT, rows, static_cast<hsize_t>(extra), path);
    h5::read_rows(dataset.get(), H5T_NATIVE_DOUBLE, begin, count, extra, extra_values.data(),
                  path + ": cannot read dataset /extra");
    for (std::size_t k = 0; k < extra_values.size() && bad_value.empty(); ++k)
      if (alive[k / extra] && !std::isfinite(extra_values[k]))
        bad_value = path + fmt::format(
                               ": dataset /extra holds a non-finite value ({}) for alive "
                               "particle id {}",
                               extra_values[k], b.begin + static_cast<std::int64_t>(k / extra));
  }
  if (!bad_value.empty()) throw InputError(bad_value);
  Particles p;
  p.extra_width = extra;
  std::size_t n = 0;
  for (std::uint8_t a : alive) n += a != 0;
  p.reserve(n);
  for (std::size_t i = 0; i < count; ++i) {
    if (!alive[i]) continue;
    const double* r = &dense[i * kCheckpointRow];
    p.id.push_back(b.begin + static_cast<std::int64_t>(i));
    p.x.insert(p.x.end(), r + 1, r + 4);
    p.v.insert(p.v.end(), r + 4, r + 7);
    p.C.insert(p.C.end(), r + 7, r + 16);
    p.F.insert(p.F.end(), r + 16, r + 25);
    p.state.insert(p.state.end(), r + 25, r + 25 + kStateSize);
    p.mass.push_back(r[25 + kStateSize]);
    p.vol0.push_back(r[26 + kStateSize]);
    p.flag.push_back(static_cast<std::uint8_t>(r[27 + kStateSize]));
    p.material.push_back(static_cast<std::uint8_t>(r[28 + kStateSize]));
    p.extra.insert(p.extra.end(), extra_values.begin() + static_cast<long>(i * extra),
                   extra_values.begin() + static_cast<long>((i + 1) * extra));
  }
  return p;
}

// ---- frames --------------------------------------------------------------------------------

const char* const kFrameReserved[] = {"position", "velocity", "alive"};
const char* const kRootReserved[] = {"format", "format_version", "particle_count"};

template <std::size_t N>
bool one_of(const std::string& name, const char* const (&list)[N]) {
  return std::find(std::begin(list), std::end(list), name) != std::end(list);
}

//! Why `name` cannot name a scalar field; "" when it can.
std::string field_name_problem(const std::string& name) {
  if (name.empty()) return "a scalar field has an empty name";
  for (unsigned char c : name) {
    if (!std::isalnum(c) && c != '_' && c != '-' && c != '.') {
      return "scalar field name '" + name + "' may use only letters, digits, '_', '-' and '.'";
    }
  }
  if (name == "." || name == "..") return "scalar field name '" + name + "' is not allowed";
  if (one_of(name, kFrameReserved)) return "scalar field name '" + name + "' is reserved";
  return "";
}

bool all_digits(const std::string& s) {
  return !s.empty() &&
         std::all_of(s.begin(), s.end(), [](unsigned char c) { return std::isdigit(c); });
}

std::vector<ParticleFrameInfo> list_particle_frames(hid_t file, const std::string& path) {
  std::vector<ParticleFrameInfo> frames;
  if (!h5::link_exists(file, io::kFramesGroup)) return frames;
  h5::Handle group = h5::open_group(file, io::kFramesGroup, h5::Failure::Input, path);
  std::vector<std::string> names;
  H5L_iterate_t collect = [](hid_t, const char* name, const auto*, void* out) -> herr_t {
    static_cast<std::vector<std::string>*>(out)->emplace_back(name);
    return 0;
  };
  h5::check(H5Literate(group.get(), H5_INDEX_NAME, H5_ITER_INC, nullptr, collect, &names),
            h5::Failure::Input, path + ": cannot list " + io::kFramesGroup);
  for (const std::string& name : names) {
    if (!all_digits(name) || name.size() > 9) {
      throw InputError(path + ": unexpected entry " + io::kFramesGroup + "/" + name);
    }
    ParticleFrameInfo info;
    info.index = std::stoi(name);
    h5::Handle frame = h5::open_group(group.get(), name, h5::Failure::Input, path);
    const std::string where = path + " " + io::kFramesGroup + "/" + name;
    info.time = h5::read_double_attr(frame.get(), "time", where);
    info.step = static_cast<int>(h5::read_long_attr(frame.get(), "step", where));
    info.fields = h5::read_string_list_attr(frame.get(), "fields", where);
    frames.push_back(info);
  }
  std::sort(
      frames.begin(), frames.end(),
      [](const ParticleFrameInfo& a, const ParticleFrameInfo& b) { return a.index < b.index; });
  return frames;
}

// ---- OpenVDB -------------------------------------------------------------------------------

void initialize_openvdb_once() {
  static std::once_flag flag;
  std::call_once(flag, [] { openvdb::initialize(); });
}

//! Splats rows (id, x, v, mass) and writes the grids to `path`; the message on failure.
std::string write_vdb_serial(const std::string& path, const std::vector<double>& rows, int width,
                             double h) {
  initialize_openvdb_once();
  auto mass = openvdb::DoubleGrid::create(0.0);
  auto momentum = openvdb::Vec3DGrid::create(openvdb::Vec3d(0.0));
  auto mass_acc = mass->getAccessor();
  auto mom_acc = momentum->getAccessor();
  const std::size_t n = rows.size() / width;
  std::size_t skipped = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double* r = &rows[i * width];
    const double m = r[7];
    double q[3];
    bool ok = std::isfinite(m);
    for (int a = 0; a < 3; ++a) {
      q[a] = r[1 + a] / h;
      ok = ok && std::isfinite(q[a]) && std::abs(q[a]) < 1e9 && std::isfinite(r[4 + a]);
    }
    if (!ok) {
      ++skipped;
      continue;
    }
    const openvdb::Coord base(static_cast<int>(std::floor(q[0])),
                              static_cast<int>(std::floor(q[1])),
                              static_cast<int>(std::floor(q[2])));
    double f[3];
    for (int a = 0; a < 3; ++a) f[a] = q[a] - std::floor(q[a]);
    for (int corner = 0; corner < 8; ++corner) {
      double w = 1;
      openvdb::Coord c = base;
      for (int a = 0; a < 3; ++a) {
        const bool up = (corner >> a) & 1;
        w *= up ? f[a] : 1.0 - f[a];
        if (up) c[a] += 1;
      }
      if (w == 0) continue;
      mass_acc.setValue(c, mass_acc.getValue(c) + w * m);
      mom_acc.setValue(c, mom_acc.getValue(c) + openvdb::Vec3d(r[4], r[5], r[6]) * (w * m));
    }
  }
  if (skipped > 0) {
    log::warn("{}: {} particle(s) with a non-finite or far-off position left out", path, skipped);
  }
  const auto transform = openvdb::math::Transform::createLinearTransform(h);
  auto density = openvdb::FloatGrid::create(0.0f);
  auto velocity = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
  auto density_acc = density->getAccessor();
  auto velocity_acc = velocity->getAccessor();
  const double cell_volume = h * h * h;
  for (auto it = mass->cbeginValueOn(); it; ++it) {
    const openvdb::Coord c = it.getCoord();
    const double m = *it;
    density_acc.setValue(c, static_cast<float>(m / cell_volume));
    const openvdb::Vec3d v = m != 0 ? mom_acc.getValue(c) / m : openvdb::Vec3d(0.0);
    velocity_acc.setValue(c, openvdb::Vec3s(static_cast<float>(v[0]), static_cast<float>(v[1]),
                                            static_cast<float>(v[2])));
  }
  density->setName("density");
  density->setGridClass(openvdb::GRID_FOG_VOLUME);
  density->setTransform(transform);
  density->insertMeta("particle_count", openvdb::Int64Metadata(static_cast<std::int64_t>(n)));
  velocity->setName("velocity");
  velocity->setVectorType(openvdb::VEC_CONTRAVARIANT_RELATIVE);
  velocity->setTransform(transform->copy());
  openvdb::GridPtrVec grids{density, velocity};
  openvdb::MetaMap file_meta;
  file_meta.insertMeta("creator", openvdb::StringMetadata("gen4d"));

  const std::string temp = io::temp_beside(path);
  try {
    openvdb::io::File file(temp);
    file.write(grids, file_meta);
    file.close();
  } catch (const std::exception& e) {
    std::remove(temp.c_str());
    std::string what = e.what();
    std::replace(what.begin(), what.end(), '\n', ' ');
    return path + ": cannot write " + temp + ": " + what;
  }
  return io::try_rename_into_place(temp, path);
}

}  // namespace

// ---- id blocks ---------------------------------------------------------------------------------

IdBlock id_block(std::int64_t total, int rank, int size) {
  const auto edge = [&](int r) {
    return static_cast<std::int64_t>(static_cast<__int128>(total) * r / size);
  };
  return {edge(rank), edge(rank + 1) - edge(rank)};
}

int id_block_owner(std::int64_t id, std::int64_t total, int size) {
  auto r = static_cast<int>(static_cast<__int128>(id) * size / total);
  // Block r starts at floor(r total / size) <= id; a later block may start at id too.
  while (r + 1 < size && id_block(total, r + 1, size).begin <= id) ++r;
  return r;
}

// ---- checkpoints ---------------------------------------------------------------------------

std::string write_particle_checkpoint(MPI_Comm comm, const std::string& dir,
                                      const ParticleCheckpointState& state, int keep) {
  const std::string final_path = io::checkpoint_path(dir, state.step);
  std::string error;
  if (state.particles == nullptr) {
    error = final_path + ": no particles given";
  } else if (state.total_particles < 0 || state.total_particles > kMaxParticles) {
    error = final_path + fmt::format(": particle count {} is out of range", state.total_particles);
  } else if (state.state_names.size() > static_cast<std::size_t>(kStateSize)) {
    error = final_path +
            fmt::format(": {} state names, at most {}", state.state_names.size(), kStateSize);
  } else if (std::string why = inconsistent(*state.particles); !why.empty()) {
    error = final_path + ": " + why;
  } else if (state.particles->extra_width != static_cast<int>(state.extra_names.size())) {
    error = final_path + fmt::format(": {} extra names for particles with {} extra values",
                                     state.extra_names.size(), state.particles->extra_width);
  }
  io::prepare_checkpoint_dir(comm, dir, error);
  const DenseBlock dense =
      to_blocks(comm, state.total_particles, kCheckpointRow + state.particles->extra_width,
                checkpoint_rows(*state.particles), final_path + ": ");
  return io::commit_checkpoint_file(comm, dir, state.step, keep, [&](hid_t file) {
    write_checkpoint_contents(file, state, dense);
  });
}

ParticleCheckpointMeta read_particle_checkpoint_meta(MPI_Comm comm, const std::string& path) {
  h5::silence_errors();
  std::string packed, error;
  if (parallel::rank(comm) == 0) {
    try {
      packed = pack(read_meta_serial(path));
    } catch (const std::exception& e) {
      error = e.what();
    }
  }
  throw_if_any<InputError>(comm, error);
  return unpack(parallel::broadcast(comm, packed, 0));
}

ParticleCheckpointMeta read_particle_checkpoint(MPI_Comm comm, const std::string& path,
                                                Particles& particles) {
  ParticleCheckpointMeta meta = read_particle_checkpoint_meta(comm, path);
  std::string error;
  h5::Handle file;
  try {
    file = h5::open_file(comm, path, false);
    if (check_checkpoint_layout(file.get(), path) != meta.total_particles) {
      error = path + ": the file changed while it was read";
    }
  } catch (const std::exception& e) {
    error = e.what();
  }
  throw_if_any<InputError>(comm, error);
  Particles read;
  try {
    const IdBlock block =
        id_block(meta.total_particles, parallel::rank(comm), parallel::size(comm));
    read = read_block(file.get(), path, meta.total_particles, block,
                      static_cast<int>(meta.extra_names.size()));
  } catch (const std::exception& e) {
    error = e.what();
  }
  // Closing is collective: every rank closes, also one whose block was bad.
  try {
    file.close(h5::Failure::Input, path + ": cannot close");
  } catch (const std::exception& e) {
    if (error.empty()) error = e.what();
  }
  throw_if_any<InputError>(comm, error);
  std::swap(particles, read);
  return meta;
}

// ---- frames --------------------------------------------------------------------------------

ParticleFrameWriter::ParticleFrameWriter(io::FramesFile file, std::int64_t total)
    : file_(std::move(file)), total_(total) {}

ParticleFrameWriter::ParticleFrameWriter(MPI_Comm comm, const std::string& h5_path,
                                         std::int64_t total_particles,
                                         const std::map<std::string, std::string>& attributes)
    : total_(total_particles) {
  if (total_particles < 0 || total_particles > kMaxParticles) {
    throw RuntimeError(h5_path +
                       fmt::format(": particle count {} is out of range", total_particles));
  }
  for (const auto& entry : attributes) {
    if (one_of(entry.first, kRootReserved)) {
      throw RuntimeError(h5_path + ": attribute '" + entry.first + "' is reserved");
    }
  }
  file_ = io::FramesFile::create(comm, h5_path, [&](hid_t root) {
    for (const auto& [name, value] : attributes) h5::write_attr(root, name, value);
    h5::write_attr(root, "format", std::string(kParticleFramesFormat));
    h5::write_attr(root, "format_version", kParticleFramesFormatVersion);
    h5::write_attr(root, "particle_count", static_cast<long>(total_particles));
  });
  commit();
}

ParticleFrameWriter ParticleFrameWriter::open_append(MPI_Comm comm, const std::string& h5_path,
                                                     int keep_up_to_step) {
  std::string error;
  h5::Handle file;
  std::int64_t total = 0;
  std::vector<ParticleFrameInfo> stored;
  try {
    file = h5::open_file(comm, h5_path, true);
    h5::check_format(file.get(), h5_path, "particle frames file", kParticleFramesFormat,
                     kParticleFramesFormatVersion, kParticleFramesFormatVersion);
    total = h5::read_long_attr(file.get(), "particle_count", h5_path);
    if (total < 0 || total > kMaxParticles) {
      throw InputError(h5_path + ": particle_count " + std::to_string(total) + " is out of range");
    }
    stored = list_particle_frames(file.get(), h5_path);
  } catch (const std::exception& e) {
    error = e.what();
  }
  throw_if_any<InputError>(comm, error);
  ParticleFrameWriter writer(io::FramesFile(comm, h5_path, std::move(file)), total);
  if (!h5::link_exists(writer.file_.get(), io::kFramesGroup)) {
    h5::create_group(writer.file_.get(), io::kFramesGroup);
  }
  for (const ParticleFrameInfo& frame : stored) {
    if (frame.step <= keep_up_to_step)
      writer.frames_.push_back(frame);
    else
      writer.file_.remove_group(io::frame_group(frame.index));
  }
  writer.commit();
  return writer;
}

void ParticleFrameWriter::commit() {
  file_.commit(
      [&](const std::string& h5_name) { return particle_xdmf_text(h5_name, total_, frames_); });
}

void ParticleFrameWriter::write_frame(double time, int step, const Particles& particles,
                                      const std::vector<ParticleScalar>& fields) {
  const std::string where = path() + fmt::format(": frame at step {}: ", step);
  std::string error = inconsistent(particles);
  std::vector<std::string> names;
  for (const ParticleScalar& f : fields) {
    if (!error.empty()) break;
    error = field_name_problem(f.name);
    if (error.empty() && std::find(names.begin(), names.end(), f.name) != names.end()) {
      error = "scalar field '" + f.name + "' is given twice";
    }
    if (error.empty() && f.values == nullptr && particles.size() > 0) {
      error = "scalar field '" + f.name + "' has no values";
    }
    names.push_back(f.name);
  }
  file_.raise_if_any(error.empty() ? "" : where + error);
  std::string joined;
  for (const std::string& name : names) joined += name + "\n";
  if (parallel::broadcast(file_.comm(), joined, 0) != joined) {
    error = where + "the scalar fields differ between ranks";
  }
  file_.raise_if_any(error);

  const int nf = static_cast<int>(fields.size());
  const int width = 7 + nf;
  std::vector<double> rows(particles.size() * width);
  for (std::size_t i = 0; i < particles.size(); ++i) {
    double* r = &rows[i * width];
    particles.pack_motion(i, r);
    for (int f = 0; f < nf; ++f) r[7 + f] = fields[f].values[i];
  }
  const DenseBlock dense = to_blocks(file_.comm(), total_, width, rows, where);

  const int index = frames_.empty() ? 0 : frames_.back().index + 1;
  const auto n = static_cast<hsize_t>(total_);
  const auto begin = static_cast<hsize_t>(dense.block.begin);
  const auto count = static_cast<hsize_t>(dense.block.count);
  file_.write_group(io::frame_group(index), where, [&](hid_t group) {
    h5::write_attr(group, "time", time);
    h5::write_attr(group, "step", static_cast<long>(step));
    h5::write_string_list_attr(group, "fields", names);
    for (const char* name : {"position", "velocity"}) {
      const std::vector<double> values = column(dense, name[0] == 'p' ? 1 : 4, 3);
      h5::Handle dataset = h5::create_rows_dataset(group, name, H5T_IEEE_F64LE, n, 3);
      h5::write_rows(dataset.get(), H5T_NATIVE_DOUBLE, begin, count, 3, values.data());
    }
    h5::Handle alive = h5::create_rows_dataset(group, "alive", H5T_STD_U8LE, n, 1);
    h5::write_rows(alive.get(), H5T_NATIVE_UINT8, begin, count, 1, dense.alive.data());
    for (int f = 0; f < nf; ++f) {
      const std::vector<double> values = column(dense, 7 + f, 1);
      h5::Handle dataset = h5::create_rows_dataset(group, names[f], H5T_IEEE_F64LE, n, 1);
      h5::write_rows(dataset.get(), H5T_NATIVE_DOUBLE, begin, count, 1, values.data());
    }
  });
  frames_.push_back({index, step, time, names});
  commit();
}

void ParticleFrameWriter::close() {
  file_.close();
}

std::string particle_xdmf_text(const std::string& h5_name, std::int64_t total_particles,
                               const std::vector<ParticleFrameInfo>& frames) {
  const std::string n = std::to_string(total_particles);
  io::XdmfCollection x("particles", h5_name);
  for (const ParticleFrameInfo& frame : frames) {
    const std::string group = io::frame_group(frame.index);
    x.begin_grid(
        frame.index, frame.time,
        "TopologyType=\"Polyvertex\" NumberOfElements=\"" + n + "\" NodesPerElement=\"1\"");
    x.geometry(n + " 3", group + "/position");
    x.attribute("velocity", "Vector", "Node", n + " 3", "Float", 8, group + "/velocity");
    x.attribute("alive", "Scalar", "Node", n, "UChar", 1, group + "/alive");
    for (const std::string& field : frame.fields)
      x.attribute(field, "Scalar", "Node", n, "Float", 8, group + "/" + field);
    x.end_grid();
  }
  return x.text();
}

// ---- point clouds and images ---------------------------------------------------------------

namespace {
//! Rows (id, x, v) of every particle, with the mass when `with_mass`, in id order on rank 0.
//! Collective; RuntimeError naming `path` on every rank when a rank's arrays are inconsistent.
std::vector<double> gather_id_x_v(MPI_Comm comm, const std::string& path,
                                  const Particles& particles, bool with_mass) {
  const std::string error = inconsistent(particles);
  throw_if_any<RuntimeError>(comm, error.empty() ? "" : path + ": " + error);
  const int W = with_mass ? 8 : 7;
  std::vector<double> rows(particles.size() * W);
  for (std::size_t i = 0; i < particles.size(); ++i) {
    particles.pack_motion(i, &rows[i * W]);
    if (with_mass) rows[i * W + 7] = particles.mass[i];
  }
  return gather_rows(comm, W, rows, path + ": ");
}
}  // namespace

void write_particle_ply(MPI_Comm comm, const std::string& path, const Particles& particles) {
  constexpr int W = 7;
  const std::vector<double> all = gather_id_x_v(comm, path, particles, false);
  std::string error;
  if (parallel::rank(comm) == 0) {
    const std::size_t n = all.size() / W;
    std::string bytes = fmt::format(
        "ply\nformat binary_little_endian 1.0\ncomment gen4d MPM particles in id order\n"
        "element vertex {}\nproperty float x\nproperty float y\nproperty float z\n"
        "property float vx\nproperty float vy\nproperty float vz\nend_header\n",
        n);
    const std::size_t header = bytes.size();
    bytes.resize(header + n * 6 * sizeof(float));
    char* out = &bytes[header];
    for (std::size_t i = 0; i < n; ++i) {
      for (int k = 0; k < 6; ++k) {
        const float value = static_cast<float>(all[i * W + 1 + k]);
        unsigned char le[4];
        std::uint32_t u = 0;
        std::memcpy(&u, &value, 4);
        for (int b = 0; b < 4; ++b) le[b] = static_cast<unsigned char>(u >> (8 * b));
        std::memcpy(out, le, 4);
        out += 4;
      }
    }
    error = io::try_write_atomically(path, bytes, io::temp_beside(path));
  }
  throw_if_any<RuntimeError>(comm, error);
}

void write_particle_vdb(MPI_Comm comm, const std::string& path, const Particles& particles,
                        double voxel_size) {
  if (!(voxel_size > 0) || !std::isfinite(voxel_size)) {
    throw InputError(path + fmt::format(": VDB voxel size must be positive, got {}", voxel_size));
  }
  constexpr int W = 8;
  // Sorted by id, so the file does not depend on how the particles were distributed.
  const std::vector<double> all = gather_id_x_v(comm, path, particles, true);
  std::string error;
  if (parallel::rank(comm) == 0) {
    try {
      error = write_vdb_serial(path, all, W, voxel_size);
    } catch (const std::exception& e) {
      error = path + ": " + e.what();
    }
  }
  throw_if_any<RuntimeError>(comm, error);
}

void write_particle_png(MPI_Comm comm, const std::string& path, const Particles& particles,
                        const ParticleView& view) {
  if (view.axis < 0 || view.axis > 2) {
    throw InputError(path + fmt::format(": view axis must be 0, 1 or 2, got {}", view.axis));
  }
  if (view.width <= 0 || view.height <= 0 || view.width > 16384 || view.height > 16384) {
    throw InputError(path + fmt::format(": image size {}x{} must be between 1 and 16384 pixels "
                                        "per side",
                                        view.width, view.height));
  }
  if (view.point_radius < 0 || view.point_radius > 64) {
    throw InputError(path + fmt::format(": point radius {} must be 0..64", view.point_radius));
  }
  for (int a = 0; a < 3; ++a) {
    if (!(view.lo[a] <= view.hi[a]) || !std::isfinite(view.lo[a]) || !std::isfinite(view.hi[a])) {
      throw InputError(path + ": the view box must have finite lo <= hi on every axis");
    }
  }
  const int right = view.axis == 0 ? 1 : 0, up = view.axis == 2 ? 1 : 2, depth = view.axis;
  const double extent_r = view.hi[right] - view.lo[right], extent_u = view.hi[up] - view.lo[up];
  if (!(extent_r > 0) || !(extent_u > 0)) {
    throw InputError(path + ": the view box is flat across the image");
  }
  std::string error = inconsistent(particles);
  throw_if_any<RuntimeError>(comm, error.empty() ? "" : path + ": " + error);

  const int width = view.width, height = view.height;
  const double scale = std::min(width / extent_r, height / extent_u);
  const double margin_x = 0.5 * (width - scale * extent_r);
  const double margin_y = 0.5 * (height - scale * extent_u);
  const double extent_d = view.hi[depth] - view.lo[depth];
  // Per pixel: 0 = empty, else 0.05 + 0.95 nearness (1 = nearest face of the box).
  std::vector<float> near(static_cast<std::size_t>(width) * height, 0.0f);
  const int radius = view.point_radius;
  for (std::size_t i = 0; i < particles.size(); ++i) {
    const double* p = &particles.x[3 * i];
    bool inside = true;
    for (int a = 0; a < 3; ++a) inside = inside && p[a] >= view.lo[a] && p[a] <= view.hi[a];
    if (!inside) continue;
    const double t = extent_d > 0 ? (p[depth] - view.lo[depth]) / extent_d : 0.5;
    const double nearness = view.axis == 1 ? 1.0 - t : t;
    const auto key = static_cast<float>(0.05 + 0.95 * nearness);
    const int px = static_cast<int>(std::floor(margin_x + scale * (p[right] - view.lo[right])));
    const int py =
        height - 1 - static_cast<int>(std::floor(margin_y + scale * (p[up] - view.lo[up])));
    for (int dy = -radius; dy <= radius; ++dy) {
      for (int dx = -radius; dx <= radius; ++dx) {
        if (dx * dx + dy * dy > radius * radius) continue;
        const int x = px + dx, y = py + dy;
        if (x < 0 || x >= width || y < 0 || y >= height) continue;
        float& slot = near[static_cast<std::size_t>(y) * width + x];
        slot = std::max(slot, key);
      }
    }
  }
  const int rank = parallel::rank(comm);
  std::vector<float> merged(rank == 0 ? near.size() : 0);
  parallel::max_to_root(comm, near.data(), rank == 0 ? merged.data() : nullptr,
                        static_cast<int>(near.size()));
  if (rank == 0) {
    std::vector<std::uint8_t> rgb(3 * merged.size());
    const double background[3] = {0.11, 0.12, 0.14}, base[3] = {0.98, 0.66, 0.32};
    for (std::size_t k = 0; k < merged.size(); ++k) {
      for (int c = 0; c < 3; ++c) {
        const double value =
            merged[k] > 0 ? base[c] * (0.25 + 0.75 * (merged[k] - 0.05) / 0.95) : background[c];
        rgb[3 * k + c] = static_cast<std::uint8_t>(std::lround(255 * std::clamp(value, 0.0, 1.0)));
      }
    }
    try {
      io::write_png_rgb(path, width, height, rgb);
    } catch (const std::exception& e) {
      error = e.what();
    }
  }
  throw_if_any<RuntimeError>(comm, error);
}

// ---- reading frames back -------------------------------------------------------------------

namespace {
h5::Handle open_frames_file(const std::string& path, std::int64_t& total) {
  h5::Handle file = h5::open_file_serial(path);
  if (!h5::has_attr(file.get(), "format") ||
      h5::read_string_attr(file.get(), "format", path) != kParticleFramesFormat)
    throw InputError(path + ": not a gen4d particle frames file");
  total = h5::read_long_attr(file.get(), "particle_count", path);
  if (total < 0) throw InputError(path + ": negative particle_count");
  return file;
}
}  // namespace

std::vector<ParticleFrameInfo> read_particle_frame_list(const std::string& h5_path) {
  std::int64_t total = 0;
  h5::Handle file = open_frames_file(h5_path, total);
  return list_particle_frames(file.get(), h5_path);
}

Particles read_particle_frame(const std::string& h5_path, int index) {
  std::int64_t total = 0;
  h5::Handle file = open_frames_file(h5_path, total);
  const std::string group = fmt::format("{}/{:06d}", io::kFramesGroup, index);
  const std::string where = h5_path + " " + group;
  const auto n = static_cast<hsize_t>(total);
  std::vector<double> x(3 * n), v(3 * n);
  std::vector<std::uint8_t> alive(n);
  {
    h5::Handle d = h5::open_rows_dataset(file.get(), group + "/position", H5T_FLOAT, n, 3, h5_path);
    h5::read_all(d.get(), H5T_NATIVE_DOUBLE, x.data(), where + "/position");
  }
  {
    h5::Handle d = h5::open_rows_dataset(file.get(), group + "/velocity", H5T_FLOAT, n, 3, h5_path);
    h5::read_all(d.get(), H5T_NATIVE_DOUBLE, v.data(), where + "/velocity");
  }
  {
    h5::Handle d = h5::open_rows_dataset(file.get(), group + "/alive", H5T_INTEGER, n, 1, h5_path);
    h5::read_all(d.get(), H5T_NATIVE_UINT8, alive.data(), where + "/alive");
  }
  Particles p;
  const double zero[kStateSize] = {};
  for (hsize_t i = 0; i < n; ++i)
    if (alive[i]) p.push_back(static_cast<std::int64_t>(i), &x[3 * i], &v[3 * i], 0, 0, zero);
  return p;
}

std::vector<std::string> render_particle_frames(const std::string& h5_path,
                                                const std::vector<int>& frames,
                                                const std::string& out_dir, int width, int height) {
  const auto list = read_particle_frame_list(h5_path);
  ParticleView view;
  view.width = width;
  view.height = height;
  view.lo = {1e300, 1e300, 1e300};
  view.hi = {-1e300, -1e300, -1e300};
  std::vector<Particles> loaded;
  for (int f : frames) {
    loaded.push_back(read_particle_frame(h5_path, list.at(static_cast<std::size_t>(f)).index));
    const Particles& p = loaded.back();
    for (std::size_t i = 0; i < p.size(); ++i)
      for (int a = 0; a < 3; ++a) {
        view.lo[a] = std::min(view.lo[a], p.x[3 * i + a]);
        view.hi[a] = std::max(view.hi[a], p.x[3 * i + a]);
      }
  }
  for (int a = 0; a < 3; ++a) {
    const double pad = 0.05 * (view.hi[a] - view.lo[a]) + 1e-9;
    view.lo[a] -= pad;
    view.hi[a] += pad;
  }
  // Splat radius: half the particle spacing of the first frame (its bounding box shared by
  // its particles), in pixels of the fitted view.
  if (!loaded.empty() && loaded[0].size() > 0) {
    double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
    for (std::size_t i = 0; i < loaded[0].size(); ++i)
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(lo[a], loaded[0].x[3 * i + a]);
        hi[a] = std::max(hi[a], loaded[0].x[3 * i + a]);
      }
    const double vol = std::max(hi[0] - lo[0], 1e-12) * std::max(hi[1] - lo[1], 1e-12) *
                       std::max(hi[2] - lo[2], 1e-12);
    const double spacing = std::cbrt(vol / static_cast<double>(loaded[0].size()));
    const double per_pixel =
        std::max((view.hi[0] - view.lo[0]) / width, (view.hi[2] - view.lo[2]) / height);
    view.point_radius = std::clamp(static_cast<int>(0.5 * spacing / per_pixel), 1, 8);
  }
  std::vector<std::string> written;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const std::string path =
        (std::filesystem::path(out_dir) /
         fmt::format("particles_{:06d}.png", list[static_cast<std::size_t>(frames[k])].index))
            .string();
    write_particle_png(MPI_COMM_SELF, path, loaded[k], view);
    written.push_back(path);
  }
  return written;
}

}  // namespace gen4d::mpm
