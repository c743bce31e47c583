// MPM particle files at 1, 2 and 4 ranks: checkpoint round trips by id, contents independent
// of the rank count, bad files, failed writes, frames with their XDMF index, PLY, VDB, PNG.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <openvdb/openvdb.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <set>

#include "core/Error.hpp"
#include "io/Checkpoint.hpp"
#include "io/FrameLayout.hpp"
#include "io/SurfaceIO.hpp"
#include "mpm/ParticleIO.hpp"
#include "png_test_util.hpp"
#include "mpi_test_util.hpp"

namespace gen4d::mpm {
namespace {

namespace fs = std::filesystem;

using test::rank_of;
using test::size_of;

int world_rank() {
  return rank_of(MPI_COMM_WORLD);
}
int world_size() {
  return size_of(MPI_COMM_WORLD);
}

//! An empty folder for one test at this rank count, shared by all ranks.
std::string scratch_dir(const std::string& name) {
  return test::scratch_dir("mpm_io/" + name);
}

using test::bytes_of;

//! `write` must throw RuntimeError on every rank, with `expected` in the message.
template <class Write>
void expect_runtime_error(Write write, const std::string& expected) {
  try {
    write();
    ADD_FAILURE() << "no error; expected one with: " << expected;
  } catch (const RuntimeError& e) {
    EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
  }
}

constexpr std::int64_t kTotal = 37;  // not a multiple of 2 or 4: unequal id blocks
const std::set<std::int64_t> kRemoved{3, 17, 36};

//! Reference values of particle `id`: every field distinct and with full-precision bits.
void reference_particle(std::int64_t id, Particles& p) {
  const double t = static_cast<double>(id);
  const double pos[3] = {0.05 * (id % 5) + 1e-3 * std::sin(t), 0.05 * ((id / 5) % 4) + 0.3,
                         0.05 * (id / 20) + 1e-3 * std::cos(1.7 * t)};
  const double vel[3] = {std::sin(0.3 * t), std::cos(0.7 * t) - 0.5, 1.0 / (t + 3.0)};
  double state[kStateSize];
  for (int k = 0; k < kStateSize; ++k) state[k] = std::sin(t + 0.1 * k) / 3.0;
  p.push_back(id, pos, vel, 1e-3 * (1.0 + t / 7.0), 1.25e-7 * (1.0 + std::sin(t) / 9.0), state);
  const std::size_t i = p.size() - 1;
  for (int k = 0; k < 9; ++k) {
    p.C[9 * i + k] = std::sin(1.1 * t + k) / 7.0;
    p.F[9 * i + k] += std::cos(0.9 * t - k) / 11.0;
  }
  p.flag[i] = static_cast<std::uint8_t>(id % 4);
  p.material[i] = static_cast<std::uint8_t>(id % 3);
}

//! The reference particles of `comm`'s rank: ids not removed with (7 id + 3) % size == rank,
//! in decreasing order (not the order of the file), or all of them on one rank.
Particles my_particles(MPI_Comm comm) {
  const int rank = rank_of(comm), size = size_of(comm);
  Particles p;
  for (std::int64_t id = kTotal - 1; id >= 0; --id) {
    if (kRemoved.count(id) || (7 * id + 3) % size != rank) continue;
    reference_particle(id, p);
  }
  return p;
}

//! The reference particles with ids in [begin, end), sorted by id.
Particles expected_range(std::int64_t begin, std::int64_t end) {
  Particles p;
  for (std::int64_t id = begin; id < end; ++id) {
    if (!kRemoved.count(id)) reference_particle(id, p);
  }
  return p;
}

template <class T>
bool same_bits(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0;
}

void expect_same_particles(const Particles& a, const Particles& b) {
  EXPECT_EQ(a.id, b.id);
  EXPECT_TRUE(same_bits(a.x, b.x));
  EXPECT_TRUE(same_bits(a.v, b.v));
  EXPECT_TRUE(same_bits(a.C, b.C));
  EXPECT_TRUE(same_bits(a.F, b.F));
  EXPECT_TRUE(same_bits(a.state, b.state));
  EXPECT_TRUE(same_bits(a.mass, b.mass));
  EXPECT_TRUE(same_bits(a.vol0, b.vol0));
  EXPECT_EQ(a.flag, b.flag);
  EXPECT_EQ(a.material, b.material);
}

ParticleCheckpointState make_state(int step, const Particles& p) {
  ParticleCheckpointState s;
  s.step = step;
  s.time = 0.001 * step + 1.0 / 7.0;
  s.frame_index = 4;
  s.next_frame_time = 0.0625;
  // Longer than the 64 KiB limit of compact attribute storage.
  s.deck_text = "[simulation]\n" + std::string(70000, '#') + "\nend = 1\n";
  s.total_particles = kTotal;
  s.state_names = {"plastic_strain", "damage"};
  s.extras = {{"dt", 1.5e-5}, {"energy", -2.25}};
  s.particles = &p;
  return s;
}

TEST(ParticleIO, IdBlocksCoverEveryIdOnce) {
  for (std::int64_t total : {0, 1, 3, 7, 37, 1000}) {
    for (int size : {1, 2, 3, 4, 7}) {
      std::int64_t next = 0;
      for (int r = 0; r < size; ++r) {
        const IdBlock b = id_block(total, r, size);
        EXPECT_EQ(b.begin, next);
        for (std::int64_t id = b.begin; id < b.begin + b.count; ++id)
          EXPECT_EQ(id_block_owner(id, total, size), r) << total << " " << size << " " << id;
        next = b.begin + b.count;
      }
      EXPECT_EQ(next, total);
    }
  }
}

TEST(ParticleCheckpoint, RoundTripGivesBackTheSameParticlesById) {
  const std::string dir = scratch_dir("round_trip");
  const Particles mine = my_particles(MPI_COMM_WORLD);
  const ParticleCheckpointState state = make_state(42, mine);
  const std::string path = write_particle_checkpoint(MPI_COMM_WORLD, dir, state, 2);
  EXPECT_EQ(path, io::checkpoint_path(dir, 42));
  EXPECT_EQ(io::latest_checkpoint(dir), path);

  const ParticleCheckpointMeta meta = read_particle_checkpoint_meta(MPI_COMM_WORLD, path);
  EXPECT_EQ(meta.step, 42);
  EXPECT_EQ(meta.time, state.time);
  EXPECT_EQ(meta.frame_index, 4);
  EXPECT_EQ(meta.next_frame_time, 0.0625);
  EXPECT_EQ(meta.deck_text, state.deck_text);
  EXPECT_EQ(meta.total_particles, kTotal);
  EXPECT_EQ(meta.state_names, state.state_names);
  EXPECT_EQ(meta.extras, state.extras);

  // Each rank gets the alive particles of its id block, sorted; removed ids stay absent.
  Particles back;
  const ParticleCheckpointMeta again = read_particle_checkpoint(MPI_COMM_WORLD, path, back);
  EXPECT_EQ(again.step, 42);
  const IdBlock block = id_block(kTotal, world_rank(), world_size());
  expect_same_particles(back, expected_range(block.begin, block.begin + block.count));
  for (std::int64_t id : back.id) EXPECT_EQ(kRemoved.count(id), 0u);
  long count = static_cast<long>(back.size()), total = 0;
  MPI_Allreduce(&count, &total, 1, MPI_LONG, MPI_SUM, MPI_COMM_WORLD);
  EXPECT_EQ(total, kTotal - static_cast<long>(kRemoved.size()));

  // A 1-rank restart of a file written at any rank count gets the whole set.
  Particles whole;
  read_particle_checkpoint(MPI_COMM_SELF, path, whole);
  expect_same_particles(whole, expected_range(0, kTotal));
}

//! The raw bytes of dataset `name`, read in its own (native) type.
std::string dataset_bytes(hid_t file, const std::string& name) {
  hid_t dataset = H5Dopen2(file, name.c_str(), H5P_DEFAULT);
  if (dataset < 0) return "<missing>";
  hid_t file_type = H5Dget_type(dataset);
  hid_t type = H5Tget_native_type(file_type, H5T_DIR_ASCEND);
  hid_t space = H5Dget_space(dataset);
  const auto n = static_cast<std::size_t>(H5Sget_simple_extent_npoints(space));
  std::string bytes(n * H5Tget_size(type), '\0');
  if (n > 0) H5Dread(dataset, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, bytes.data());
  H5Sclose(space);
  H5Tclose(type);
  H5Tclose(file_type);
  H5Dclose(dataset);
  return bytes;
}

const char* const kDatasets[] = {"position", "velocity", "C",       "F",     "state",
                                 "mass",     "flag",     "volume0", "alive", "material"};

TEST(ParticleCheckpoint, FileContentDoesNotDependOnTheRankCount) {
  const std::string dir = scratch_dir("rank_counts");
  const Particles mine = my_particles(MPI_COMM_WORLD);
  const std::string at_world =
      write_particle_checkpoint(MPI_COMM_WORLD, dir + "/world", make_state(9, mine), 0);
  // Rank 0 alone, with every particle.
  std::string at_one;
  if (world_rank() == 0) {
    const Particles all = my_particles(MPI_COMM_SELF);
    at_one = write_particle_checkpoint(MPI_COMM_SELF, dir + "/one", make_state(9, all), 0);
  }
  // Ranks 0 and 1 with their own distribution.
  std::string at_two;
  MPI_Comm pair = MPI_COMM_NULL;
  MPI_Comm_split(MPI_COMM_WORLD, world_rank() < 2 ? 0 : MPI_UNDEFINED, world_rank(), &pair);
  if (pair != MPI_COMM_NULL) {
    const Particles half = my_particles(pair);
    at_two = write_particle_checkpoint(pair, dir + "/two", make_state(9, half), 0);
    MPI_Comm_free(&pair);
  }
  if (world_rank() == 0)
    [&] {
      std::vector<std::string> others{at_one};
      if (!at_two.empty()) others.push_back(at_two);
      const ParticleCheckpointMeta reference =
          read_particle_checkpoint_meta(MPI_COMM_SELF, at_world);
      hid_t world_file = H5Fopen(at_world.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
      ASSERT_GE(world_file, 0);
      for (const std::string& other : others) {
        const ParticleCheckpointMeta meta = read_particle_checkpoint_meta(MPI_COMM_SELF, other);
        EXPECT_EQ(meta.deck_text, reference.deck_text);
        EXPECT_EQ(meta.time, reference.time);
        EXPECT_EQ(meta.state_names, reference.state_names);
        EXPECT_EQ(meta.extras, reference.extras);
        hid_t file = H5Fopen(other.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
        ASSERT_GE(file, 0);
        for (const char* name : kDatasets) {
          const std::string a = dataset_bytes(world_file, name), b = dataset_bytes(file, name);
          EXPECT_FALSE(a.empty()) << name;
          EXPECT_EQ(a, b) << other << " dataset " << name;
        }
        H5Fclose(file);
      }
      H5Fclose(world_file);
    }();
  MPI_Barrier(MPI_COMM_WORLD);
}

TEST(ParticleCheckpoint, KeepsTheNewestAndLeavesNoTemporaries) {
  const std::string dir = scratch_dir("keep");
  const Particles mine = my_particles(MPI_COMM_WORLD);
  for (int step : {100, 200, 300, 400}) {
    write_particle_checkpoint(MPI_COMM_WORLD, dir, make_state(step, mine), 2);
  }
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir))
    names.push_back(entry.path().filename().string());
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, (std::vector<std::string>{"checkpoint_00000300.h5", "checkpoint_00000400.h5"}));
  EXPECT_EQ(io::latest_checkpoint(dir), io::checkpoint_path(dir, 400));
  MPI_Barrier(MPI_COMM_WORLD);  // nobody deletes while another rank still lists
}

TEST(ParticleCheckpoint, EmptyRunsAndEmptyRanksRoundTrip) {
  const std::string dir = scratch_dir("empty");
  // Only the last rank holds particles; the others join with nothing.
  Particles mine;
  if (world_rank() == world_size() - 1) mine = my_particles(MPI_COMM_SELF);
  std::string path = write_particle_checkpoint(MPI_COMM_WORLD, dir, make_state(1, mine), 0);
  Particles back;
  read_particle_checkpoint(MPI_COMM_WORLD, path, back);
  const IdBlock block = id_block(kTotal, world_rank(), world_size());
  expect_same_particles(back, expected_range(block.begin, block.begin + block.count));

  // No particles at all (N = 0), and no state names.
  Particles none;
  ParticleCheckpointState state = make_state(2, none);
  state.total_particles = 0;
  state.state_names.clear();
  path = write_particle_checkpoint(MPI_COMM_WORLD, dir, state, 0);
  const ParticleCheckpointMeta meta = read_particle_checkpoint(MPI_COMM_WORLD, path, back);
  EXPECT_EQ(meta.total_particles, 0);
  EXPECT_TRUE(meta.state_names.empty());
  EXPECT_EQ(back.size(), 0u);
}

// ---- bad files -----------------------------------------------------------------------------

//! Runs `edit` on an HDF5 copy of `good` at `path` (rank 0), then waits for it on every rank.
template <class Edit>
void damaged_copy(const std::string& good, const std::string& path, Edit edit) {
  if (world_rank() == 0) {
    fs::copy_file(good, path, fs::copy_options::overwrite_existing);
    hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    EXPECT_GE(file, 0);
    if (file >= 0) {
      edit(file);
      H5Fclose(file);
    }
  }
  MPI_Barrier(MPI_COMM_WORLD);
}

void set_attr(hid_t obj, const char* name, hid_t type, const void* value) {
  H5Adelete(obj, name);
  hid_t space = H5Screate(H5S_SCALAR);
  hid_t attr = H5Acreate2(obj, name, type, space, H5P_DEFAULT, H5P_DEFAULT);
  H5Awrite(attr, type, value);
  H5Aclose(attr);
  H5Sclose(space);
}

void replace_dataset(hid_t file, const char* name, std::vector<hsize_t> shape) {
  H5Ldelete(file, name, H5P_DEFAULT);
  hid_t space = H5Screate_simple(static_cast<int>(shape.size()), shape.data(), nullptr);
  hid_t dataset =
      H5Dcreate2(file, name, H5T_IEEE_F64LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  H5Dclose(dataset);
  H5Sclose(space);
}

//! Both readers must throw InputError naming `path` (and `expected` text) on every rank,
//! leaving the caller's particles untouched.
void expect_rejected(const std::string& path, const std::string& expected, bool meta_too = true) {
  Particles sentinel;
  reference_particle(5, sentinel);
  Particles particles = sentinel;
  if (meta_too) {
    try {
      read_particle_checkpoint_meta(MPI_COMM_WORLD, path);
      ADD_FAILURE() << path << ": metadata read without error";
    } catch (const InputError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(path), std::string::npos) << what;
      EXPECT_NE(what.find(expected), std::string::npos) << what;
    }
  }
  try {
    read_particle_checkpoint(MPI_COMM_WORLD, path, particles);
    ADD_FAILURE() << path << ": read without error";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(path), std::string::npos) << what;
    EXPECT_NE(what.find(expected), std::string::npos) << what;
  }
  expect_same_particles(particles, sentinel);
}

TEST(ParticleCheckpoint, BadFilesAreInputErrorsNamingTheFile) {
  const std::string dir = scratch_dir("bad_files");
  const Particles mine = my_particles(MPI_COMM_WORLD);
  const std::string good = write_particle_checkpoint(MPI_COMM_WORLD, dir, make_state(1, mine), 0);

  expect_rejected(dir + "/absent.h5", "no such file");

  const std::string text = dir + "/text.h5";
  if (world_rank() == 0) std::ofstream(text) << "not an HDF5 file\n";
  MPI_Barrier(MPI_COMM_WORLD);
  expect_rejected(text, "not an HDF5 file");

  const std::string truncated = dir + "/truncated.h5";
  if (world_rank() == 0) {
    const std::string bytes = bytes_of(good);
    std::ofstream(truncated, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  }
  MPI_Barrier(MPI_COMM_WORLD);
  expect_rejected(truncated, "");

  const std::string no_format = dir + "/no_format.h5";
  damaged_copy(good, no_format, [](hid_t f) { H5Adelete(f, "format"); });
  expect_rejected(no_format, "no 'format' attribute");

  const std::string foreign = dir + "/foreign.h5";
  damaged_copy(good, foreign, [](hid_t f) {
    const char text[] = "gen4d-checkpoint";
    hid_t type = H5Tcopy(H5T_C_S1);
    H5Tset_size(type, sizeof text);
    set_attr(f, "format", type, text);
    H5Tclose(type);
  });
  expect_rejected(foreign, "format is 'gen4d-checkpoint'");

  const std::string version = dir + "/version.h5";
  damaged_copy(good, version, [](hid_t f) {
    const long three = 3;
    set_attr(f, "format_version", H5T_NATIVE_LONG, &three);
  });
  expect_rejected(version, "format_version 3 is not supported");

  const std::string missing = dir + "/missing_dataset.h5";
  damaged_copy(good, missing, [](hid_t f) { H5Ldelete(f, "F", H5P_DEFAULT); });
  expect_rejected(missing, "missing dataset /F");

  const std::string shape = dir + "/shape.h5";
  damaged_copy(good, shape, [](hid_t f) { replace_dataset(f, "mass", {kTotal + 1}); });
  expect_rejected(shape, "dataset /mass has shape [38], expected [37]");

  const std::string state_width = dir + "/state_width.h5";
  damaged_copy(good, state_width, [](hid_t f) {
    replace_dataset(f, "state", {kTotal, kStateSize + 1});
  });
  expect_rejected(state_width, "dataset /state has shape");

  // A NaN in an alive particle's position is found by the rank reading that block.
  const std::string nan = dir + "/nan.h5";
  damaged_copy(good, nan, [](hid_t f) {
    hid_t dataset = H5Dopen2(f, "position", H5P_DEFAULT);
    hid_t space = H5Dget_space(dataset);
    const hsize_t start[2] = {30, 1}, count[2] = {1, 1};
    H5Sselect_hyperslab(space, H5S_SELECT_SET, start, nullptr, count, nullptr);
    const hsize_t one = 1;
    hid_t mem = H5Screate_simple(1, &one, nullptr);
    const double value = std::numeric_limits<double>::quiet_NaN();
    H5Dwrite(dataset, H5T_NATIVE_DOUBLE, mem, space, H5P_DEFAULT, &value);
    H5Sclose(mem);
    H5Sclose(space);
    H5Dclose(dataset);
  });
  expect_rejected(nan, "non-finite value (nan) for alive particle id 30", false);
}

// ---- failed writes -------------------------------------------------------------------------

std::vector<std::string> listing(const std::string& dir) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir))
    names.push_back(entry.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

TEST(ParticleCheckpoint, VersionOneFilesReadWithEveryMaterialSlotZero) {
  // A format_version 1 file is a version 2 file without the material dataset.
  const std::string dir = scratch_dir("version_one");
  const Particles mine = my_particles(MPI_COMM_WORLD);
  const std::string good = write_particle_checkpoint(MPI_COMM_WORLD, dir, make_state(1, mine), 0);
  const std::string old = dir + "/version1.h5";
  damaged_copy(good, old, [](hid_t f) {
    const long one = 1;
    set_attr(f, "format_version", H5T_NATIVE_LONG, &one);
    H5Ldelete(f, "material", H5P_DEFAULT);
  });
  Particles back;
  read_particle_checkpoint(MPI_COMM_WORLD, old, back);
  Particles expected = [&] {
    const IdBlock block = id_block(kTotal, world_rank(), world_size());
    return expected_range(block.begin, block.begin + block.count);
  }();
  ASSERT_GT(std::count(expected.material.begin(), expected.material.end(), 1), 0);
  std::fill(expected.material.begin(), expected.material.end(), 0);
  expect_same_particles(back, expected);
}

TEST(ParticleCheckpoint, FailedWritesLeaveNothingUnderTheFinalName) {
  const std::string dir = scratch_dir("failed_writes");
  Particles mine = my_particles(MPI_COMM_WORLD);

  // The checkpoint folder cannot be created under a plain file.
  const std::string plain = dir + "/plain_file";
  if (world_rank() == 0) std::ofstream(plain) << "occupied";
  MPI_Barrier(MPI_COMM_WORLD);
  expect_runtime_error(
      [&] { write_particle_checkpoint(MPI_COMM_WORLD, plain + "/ckpt", make_state(1, mine), 0); },
      "cannot create the checkpoint directory");

  // An id outside 0..N-1 on one rank, or an id held by two ranks, fails on every rank.
  const std::string out = dir + "/out";
  Particles bad = mine;
  if (world_rank() == world_size() - 1) reference_particle(kTotal, bad);
  expect_runtime_error(
      [&] { write_particle_checkpoint(MPI_COMM_WORLD, out, make_state(2, bad), 0); },
      "particle id 37 is outside 0..36");
  bad = mine;
  if (world_rank() == 0) reference_particle(kTotal - 2, bad);  // held already by some rank
  expect_runtime_error(
      [&] { write_particle_checkpoint(MPI_COMM_WORLD, out, make_state(3, bad), 0); },
      "particle id 35 is held twice");

  // HDF5 fails in the middle of writing the file (an attribute with an empty name): the
  // temporary is removed and the final name never appears.
  ParticleCheckpointState state = make_state(4, mine);
  state.extras[""] = 1.0;
  expect_runtime_error([&] { write_particle_checkpoint(MPI_COMM_WORLD, out, state, 0); },
                       ".checkpoint_00000004.h5.tmp): cannot create attribute ''");

  // The temporary's name is taken (as by a crashed run's leftover folder).
  if (world_rank() == 0) fs::create_directories(out + "/.checkpoint_00000005.h5.tmp/x");
  MPI_Barrier(MPI_COMM_WORLD);
  expect_runtime_error(
      [&] { write_particle_checkpoint(MPI_COMM_WORLD, out, make_state(5, mine), 0); },
      ".checkpoint_00000005.h5.tmp): cannot create the file");
  if (world_rank() == 0) fs::remove_all(out + "/.checkpoint_00000005.h5.tmp");
  MPI_Barrier(MPI_COMM_WORLD);
  EXPECT_EQ(listing(out), std::vector<std::string>{});

  // A read-only folder (root ignores permissions, so only checked for other users).
  if (geteuid() != 0) {
    const std::string locked = dir + "/locked";
    if (world_rank() == 0) {
      fs::create_directories(locked);
      fs::permissions(locked, fs::perms::owner_read | fs::perms::owner_exec);
    }
    MPI_Barrier(MPI_COMM_WORLD);
    expect_runtime_error(
        [&] { write_particle_checkpoint(MPI_COMM_WORLD, locked, make_state(6, mine), 0); },
        "cannot create the file");
    EXPECT_EQ(listing(locked), std::vector<std::string>{});
    MPI_Barrier(MPI_COMM_WORLD);
    if (world_rank() == 0) fs::permissions(locked, fs::perms::owner_all);
  }
  MPI_Barrier(MPI_COMM_WORLD);
}

// ---- frames --------------------------------------------------------------------------------

struct Fields {
  std::vector<double> J, plastic, damage, temperature;
};

double field_value(std::int64_t id, int which, int frame) {
  return std::sin(0.37 * id + which) * (frame + 1) + which;
}

Fields make_fields(const Particles& p, int frame) {
  Fields f;
  for (std::int64_t id : p.id) {
    f.J.push_back(field_value(id, 0, frame));
    f.plastic.push_back(field_value(id, 1, frame));
    f.damage.push_back(field_value(id, 2, frame));
    f.temperature.push_back(field_value(id, 3, frame));
  }
  return f;
}

std::vector<hsize_t> dataset_shape(hid_t file, const std::string& name) {
  hid_t dataset = H5Dopen2(file, name.c_str(), H5P_DEFAULT);
  if (dataset < 0) return {};
  hid_t space = H5Dget_space(dataset);
  std::vector<hsize_t> shape(static_cast<std::size_t>(H5Sget_simple_extent_ndims(space)));
  H5Sget_simple_extent_dims(space, shape.data(), nullptr);
  H5Sclose(space);
  H5Dclose(dataset);
  return shape;
}

template <class T>
std::vector<T> read_dataset(hid_t file, const std::string& name, hid_t type) {
  const std::vector<hsize_t> shape = dataset_shape(file, name);
  std::size_t n = 1;
  for (hsize_t d : shape) n *= d;
  std::vector<T> values(n);
  hid_t dataset = H5Dopen2(file, name.c_str(), H5P_DEFAULT);
  H5Dread(dataset, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data());
  H5Dclose(dataset);
  return values;
}

std::size_t count_of(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t pos = text.find(what); pos != std::string::npos; pos = text.find(what, pos + 1))
    ++n;
  return n;
}

TEST(ParticleFrames, FramesHaveTheRightShapesAndAnIndexNamingEveryField) {
  const std::string dir = scratch_dir("frames");
  const std::string path = dir + "/particles.h5";
  const Particles mine = my_particles(MPI_COMM_WORLD);
  {
    ParticleFrameWriter writer(MPI_COMM_WORLD, path, kTotal, {{"deck", "[simulation]\n"}});
    EXPECT_EQ(writer.xdmf_path(), dir + "/particles.xdmf");
    for (int frame = 0; frame < 3; ++frame) {
      const Fields f = make_fields(mine, frame);
      std::vector<ParticleScalar> fields{
          {"J", f.J.data()}, {"plastic_strain", f.plastic.data()}, {"damage", f.damage.data()}};
      if (frame == 1) fields.push_back({"temperature", f.temperature.data()});
      writer.write_frame(0.25 * frame, 10 * (frame + 1), mine, fields);
    }
    // A bad field fails on every rank and adds no frame.
    const Fields f = make_fields(mine, 9);
    expect_runtime_error(
        [&] {
          writer.write_frame(1.0, 40, mine, {{"alive", f.J.data()}});
        },
        "particles.h5: frame at step 40: scalar field name 'alive' is reserved");
    expect_runtime_error(
        [&] {
          writer.write_frame(1.0, 40, mine, {{"a b", f.J.data()}});
        },
        "scalar field name 'a b' may use only");
    EXPECT_EQ(writer.frames().size(), 3u);
    writer.close();
  }
  if (world_rank() == 0)
    [&] {
      hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
      ASSERT_GE(file, 0);
      const hsize_t n = kTotal;
      for (int frame = 0; frame < 3; ++frame) {
        const std::string group = io::frame_group(frame) + "/";
        EXPECT_EQ(dataset_shape(file, group + "position"), (std::vector<hsize_t>{n, 3}));
        EXPECT_EQ(dataset_shape(file, group + "velocity"), (std::vector<hsize_t>{n, 3}));
        EXPECT_EQ(dataset_shape(file, group + "alive"), (std::vector<hsize_t>{n}));
        EXPECT_EQ(dataset_shape(file, group + "J"), (std::vector<hsize_t>{n}));
        EXPECT_EQ(dataset_shape(file, group + "temperature").size(), frame == 1 ? 1u : 0u);
        const auto x = read_dataset<double>(file, group + "position", H5T_NATIVE_DOUBLE);
        const auto v = read_dataset<double>(file, group + "velocity", H5T_NATIVE_DOUBLE);
        const auto alive = read_dataset<std::uint8_t>(file, group + "alive", H5T_NATIVE_UINT8);
        const auto damage = read_dataset<double>(file, group + "damage", H5T_NATIVE_DOUBLE);
        const Particles all = expected_range(0, kTotal);
        std::vector<double> want_x(3 * n, 0.0), want_v(3 * n, 0.0), want_damage(n, 0.0);
        std::vector<std::uint8_t> want_alive(n, 0);
        for (std::size_t i = 0; i < all.size(); ++i) {
          const auto id = static_cast<std::size_t>(all.id[i]);
          std::copy_n(&all.x[3 * i], 3, &want_x[3 * id]);
          std::copy_n(&all.v[3 * i], 3, &want_v[3 * id]);
          want_damage[id] = field_value(all.id[i], 2, frame);
          want_alive[id] = 1;
        }
        EXPECT_TRUE(same_bits(x, want_x));
        EXPECT_TRUE(same_bits(v, want_v));
        EXPECT_TRUE(same_bits(damage, want_damage));
        EXPECT_EQ(alive, want_alive);
      }
      H5Fclose(file);
      const std::string xdmf = bytes_of(dir + "/particles.xdmf");
      EXPECT_EQ(count_of(xdmf, "TopologyType=\"Polyvertex\" NumberOfElements=\"37\""), 3u);
      EXPECT_EQ(count_of(xdmf, "<Time Value="), 3u);
      EXPECT_EQ(count_of(xdmf, "particles.h5:/frames/000002/position"), 1u);
      for (const char* field : {"velocity", "alive", "J", "plastic_strain", "damage"})
        EXPECT_EQ(count_of(xdmf, std::string("Attribute Name=\"") + field + "\""), 3u) << field;
      EXPECT_EQ(count_of(xdmf, "Attribute Name=\"temperature\""), 1u);
      EXPECT_EQ(count_of(xdmf, "particles.h5:/frames/000001/temperature"), 1u);
    }();
  MPI_Barrier(MPI_COMM_WORLD);

  // A restart from step 20 drops the frame of step 30 and continues after frame 1.
  {
    ParticleFrameWriter writer = ParticleFrameWriter::open_append(MPI_COMM_WORLD, path, 20);
    ASSERT_EQ(writer.frames().size(), 2u);
    EXPECT_EQ(writer.frames()[1].fields,
              (std::vector<std::string>{"J", "plastic_strain", "damage", "temperature"}));
    EXPECT_EQ(writer.total_particles(), kTotal);
    const Fields f = make_fields(mine, 5);
    writer.write_frame(0.625, 25, mine, {{"J", f.J.data()}});
    ASSERT_EQ(writer.frames().size(), 3u);
    EXPECT_EQ(writer.frames()[2].index, 2);
    EXPECT_EQ(writer.frames()[2].step, 25);
    writer.close();
  }
  if (world_rank() == 0) {
    const std::string xdmf = bytes_of(dir + "/particles.xdmf");
    EXPECT_EQ(count_of(xdmf, "<Time Value="), 3u);
    EXPECT_EQ(count_of(xdmf, "<Time Value=\"0.625\"/>"), 1u);
    EXPECT_EQ(count_of(xdmf, "particles.h5:/frames/000002/damage"), 0u);
    EXPECT_EQ(count_of(xdmf, "particles.h5:/frames/000002/J"), 1u);
  }
  MPI_Barrier(MPI_COMM_WORLD);

  // Reopening something that is not a particle frames file is an InputError naming it.
  const std::string ckpt = write_particle_checkpoint(MPI_COMM_WORLD, dir, make_state(1, mine), 0);
  try {
    ParticleFrameWriter::open_append(MPI_COMM_WORLD, ckpt, 0);
    ADD_FAILURE() << "a checkpoint opened as frames";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(ckpt), std::string::npos) << e.what();
  }
}

// ---- point clouds and images ---------------------------------------------------------------

TEST(ParticleExport, PlyHasTheAliveParticlesInIdOrder) {
  const std::string dir = scratch_dir("ply");
  const std::string path = dir + "/particles.ply";
  write_particle_ply(MPI_COMM_WORLD, path, my_particles(MPI_COMM_WORLD));
  if (world_rank() == 0)
    [&] {
      const std::string bytes = bytes_of(path);
      const std::string header =
          "ply\nformat binary_little_endian 1.0\ncomment gen4d MPM particles in id order\n"
          "element vertex 34\nproperty float x\nproperty float y\nproperty float z\n"
          "property float vx\nproperty float vy\nproperty float vz\nend_header\n";
      ASSERT_EQ(bytes.substr(0, header.size()), header);
      ASSERT_EQ(bytes.size(), header.size() + 34 * 6 * sizeof(float));
      const Particles all = expected_range(0, kTotal);
      for (std::size_t i = 0; i < all.size(); ++i) {
        float values[6];
        std::memcpy(values, bytes.data() + header.size() + 24 * i,
                    24);  // the host is little-endian
        for (int k = 0; k < 3; ++k) {
          EXPECT_EQ(values[k], static_cast<float>(all.x[3 * i + k]));
          EXPECT_EQ(values[3 + k], static_cast<float>(all.v[3 * i + k]));
        }
      }
      const io::SurfaceMesh mesh = io::read_ply(path);
      EXPECT_EQ(mesh.vertex_count(), 34u);
      EXPECT_TRUE(listing(dir) == std::vector<std::string>{"particles.ply"});
    }();
  MPI_Barrier(MPI_COMM_WORLD);
  expect_runtime_error(
      [&] {
        write_particle_ply(MPI_COMM_WORLD, dir + "/absent/particles.ply",
                           my_particles(MPI_COMM_WORLD));
      },
      "absent/particles.ply: cannot create");
}

TEST(ParticleExport, VdbHoldsTheMassAndMomentum) {
  const std::string dir = scratch_dir("vdb");
  const std::string path = dir + "/particles.vdb";
  const double h = 0.04;
  const Particles mine = my_particles(MPI_COMM_WORLD);
  write_particle_vdb(MPI_COMM_WORLD, path, mine, h);
  EXPECT_THROW(write_particle_vdb(MPI_COMM_WORLD, dir + "/bad.vdb", mine, 0.0), InputError);
  if (world_rank() == 0)
    [&] {
      openvdb::initialize();
      openvdb::io::File file(path);
      file.open();
      auto density = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid("density"));
      auto velocity = openvdb::gridPtrCast<openvdb::Vec3SGrid>(file.readGrid("velocity"));
      file.close();
      ASSERT_TRUE(density);
      ASSERT_TRUE(velocity);
      EXPECT_EQ(density->getGridClass(), openvdb::GRID_FOG_VOLUME);
      EXPECT_EQ(velocity->getVectorType(), openvdb::VEC_CONTRAVARIANT_RELATIVE);
      EXPECT_NEAR(density->voxelSize()[0], h, 1e-15);
      EXPECT_NEAR(velocity->voxelSize()[2], h, 1e-15);
      // Voxel (i, j, k) is centred at (i, j, k) h.
      const openvdb::Vec3d world = density->indexToWorld(openvdb::Coord(2, -1, 3));
      EXPECT_NEAR(world[0], 2 * h, 1e-15);
      EXPECT_NEAR(world[1], -h, 1e-15);

      const Particles all = expected_range(0, kTotal);
      double mass = 0, momentum[3] = {0, 0, 0};
      for (std::size_t i = 0; i < all.size(); ++i) {
        mass += all.mass[i];
        for (int k = 0; k < 3; ++k) momentum[k] += all.mass[i] * all.v[3 * i + k];
      }
      double grid_mass = 0, grid_momentum[3] = {0, 0, 0};
      auto vel = velocity->getConstAccessor();
      for (auto it = density->cbeginValueOn(); it; ++it) {
        const double m = static_cast<double>(*it) * h * h * h;
        grid_mass += m;
        const openvdb::Vec3s u = vel.getValue(it.getCoord());
        for (int k = 0; k < 3; ++k) grid_momentum[k] += m * u[k];
      }
      EXPECT_NEAR(grid_mass, mass, 1e-6 * mass);
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(grid_momentum[k], momentum[k], 1e-5 * mass) << k;
      EXPECT_TRUE(listing(dir) == std::vector<std::string>{"particles.vdb"});
    }();
  MPI_Barrier(MPI_COMM_WORLD);
}

TEST(ParticleExport, PngSplatDoesNotDependOnTheDistribution) {
  const std::string dir = scratch_dir("png");
  ParticleView view;
  view.axis = 1;
  view.width = 96;
  view.height = 64;
  view.lo = {-0.05, 0.25, -0.05};
  view.hi = {0.30, 0.50, 0.20};
  write_particle_png(MPI_COMM_WORLD, dir + "/world.png", my_particles(MPI_COMM_WORLD), view);
  if (world_rank() == 0)
    write_particle_png(MPI_COMM_SELF, dir + "/one.png", my_particles(MPI_COMM_SELF), view);
  ParticleView flat = view;
  flat.hi[0] = flat.lo[0];
  EXPECT_THROW(write_particle_png(MPI_COMM_WORLD, dir + "/flat.png", Particles{}, flat),
               InputError);
  if (world_rank() == 0)
    [&] {
      const test::Picture picture = test::load_png(dir + "/world.png");
      ASSERT_EQ(picture.width, 96);
      ASSERT_EQ(picture.height, 64);
      const auto background = picture.at(0, 0);
      int lit = 0;
      for (int y = 0; y < picture.height; ++y)
        for (int x = 0; x < picture.width; ++x) lit += picture.at(x, y) != background;
      EXPECT_GT(lit, 20);
      EXPECT_LT(lit, 96 * 64 / 2);
      EXPECT_EQ(test::load_png(dir + "/one.png").rgb, picture.rgb);
    }();
  MPI_Barrier(MPI_COMM_WORLD);
}

}  // namespace
}  // namespace gen4d::mpm
