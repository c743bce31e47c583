// Recordings for gen4d diagnose: good CSV and HDF5 files read back exactly, and every bad file
// gives one InputError naming the file and the line (CSV) or dataset and row (HDF5).
#include <gtest/gtest.h>
#include <hdf5.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <string>
#include <vector>

#include "core/Error.hpp"
#include "diagnose/Recording.hpp"

namespace gen4d::diagnose {
namespace {

namespace fs = std::filesystem;

//! Runs `f` and expects an InputError whose message contains every one of `parts`.
void expect_input_error(const std::function<void()>& f, std::initializer_list<std::string> parts) {
  try {
    f();
  } catch (const InputError& e) {
    const std::string what = e.what();
    for (const std::string& p : parts) {
      EXPECT_NE(what.find(p), std::string::npos) << "'" << p << "' not in: " << what;
    }
    EXPECT_EQ(what.find('\n'), std::string::npos) << "not one line: " << what;
    return;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected InputError, got: " << e.what();
    return;
  }
  ADD_FAILURE() << "expected InputError, nothing thrown";
}

//! Writes root-level or grouped 1-D datasets with the plain HDF5 API.
class H5Writer {
 public:
  explicit H5Writer(const std::string& path)
      : file_(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT)) {
    EXPECT_GE(file_, 0);
  }
  ~H5Writer() { H5Fclose(file_); }
  void group(const std::string& name) {
    H5Gclose(H5Gcreate2(file_, name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT));
  }
  void numbers(const std::string& name, const std::vector<double>& v,
               hid_t file_type = H5T_IEEE_F64LE) {
    write(name, file_type, H5T_NATIVE_DOUBLE, v.size(), v.data());
  }
  void ints(const std::string& name, const std::vector<long long>& v) {
    write(name, H5T_STD_I32LE, H5T_NATIVE_LLONG, v.size(), v.data());
  }
  void vlen_strings(const std::string& name, const std::vector<std::string>& v) {
    hid_t type = H5Tcopy(H5T_C_S1);
    H5Tset_size(type, H5T_VARIABLE);
    std::vector<const char*> p;
    for (const std::string& s : v) p.push_back(s.c_str());
    write(name, type, type, v.size(), p.data());
    H5Tclose(type);
  }
  void fixed_strings(const std::string& name, const std::vector<std::string>& v, std::size_t size) {
    hid_t type = H5Tcopy(H5T_C_S1);
    H5Tset_size(type, size);
    H5Tset_strpad(type, H5T_STR_NULLPAD);
    std::vector<char> buffer(v.size() * size, '\0');
    for (std::size_t i = 0; i < v.size(); ++i) v[i].copy(buffer.data() + i * size, size);
    write(name, type, type, v.size(), buffer.data());
    H5Tclose(type);
  }

 private:
  void write(const std::string& name, hid_t file_type, hid_t mem_type, std::size_t n,
             const void* data) {
    const hsize_t dims = n;
    hid_t space = H5Screate_simple(1, &dims, nullptr);
    hid_t ds =
        H5Dcreate2(file_, name.c_str(), file_type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(ds, 0) << name;
    EXPECT_GE(H5Dwrite(ds, mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), 0) << name;
    H5Dclose(ds);
    H5Sclose(space);
  }
  hid_t file_;
};

const std::string kPositionsCsv =
    "marker,X,Y,Z,t,x,y,z\n"
    "m1,0.1,0.2,0.3,0,0.1,0.2,0.3\n"
    "m2,1,0,0,0,1,0,0\n"
    "m1,0.1,0.2,0.3,0.013,0.11,0.2,0.3\n"
    "m2,1,0,0,0.02,1.5,0,-2e-3\n"
    "m1,0.1,0.2,0.3,0.05,0.12,0.21,0.3\n";

//! The recording that kPositionsCsv holds (lines are those of the CSV file).
Recording expected_positions() {
  Recording rec;
  Channel m1;
  m1.id = "m1";
  m1.X = {0.1, 0.2, 0.3};
  m1.t = {0, 0.013, 0.05};
  m1.value = {{0.1, 0.2, 0.3}, {0.11, 0.2, 0.3}, {0.12, 0.21, 0.3}};
  m1.line = {2, 4, 6};
  Channel m2;
  m2.id = "m2";
  m2.X = {1, 0, 0};
  m2.t = {0, 0.02};
  m2.value = {{1, 0, 0}, {1.5, 0, -2e-3}};
  m2.line = {3, 5};
  rec.channels = {m1, m2};
  return rec;
}

//! Channels equal in id, kind, reference point, times and values (exactly); lines optional.
void expect_same(const Recording& got, const Recording& want, bool lines = true) {
  ASSERT_EQ(got.channels.size(), want.channels.size());
  for (std::size_t k = 0; k < want.channels.size(); ++k) {
    const Channel& g = got.channels[k];
    const Channel& w = want.channels[k];
    EXPECT_EQ(g.id, w.id);
    EXPECT_EQ(g.kind, w.kind) << w.id;
    EXPECT_EQ(g.X, w.X) << w.id;
    EXPECT_EQ(g.t, w.t) << w.id;
    EXPECT_EQ(g.value, w.value) << w.id;
    if (lines) EXPECT_EQ(g.line, w.line) << w.id;
  }
}

struct RecordingTest : ::testing::Test {
  std::string dir;

  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir = (fs::path(::testing::TempDir()) /
           ("gen4d_recording_" + std::to_string(::getpid()) + "_" + info->name()))
              .string();
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  void TearDown() override { fs::remove_all(dir); }

  std::string write(const std::string& name, const std::string& text) {
    const std::string path = dir + "/" + name;
    std::ofstream(path, std::ios::binary) << text;
    return path;
  }

  //! kPositionsCsv with `line` (1-based) replaced by `text`.
  std::string positions_with(const std::string& name, int line, const std::string& text) {
    std::string all = kPositionsCsv, out;
    std::size_t start = 0;
    for (int n = 1; start < all.size(); ++n) {
      const std::size_t end = all.find('\n', start);
      out += (n == line ? text : all.substr(start, end - start)) + "\n";
      start = end + 1;
    }
    return write(name, out);
  }
};

// ------------------------------------------------------------------------------- good files

TEST_F(RecordingTest, CsvPositionsInterleavedUnevenTimes) {
  const std::string path = write("pos.csv", kPositionsCsv);
  const Recording rec = read_recording(path);
  EXPECT_EQ(rec.source, path);
  expect_same(rec, expected_positions());
  EXPECT_EQ(rec.channels[0].file, path);
  EXPECT_EQ(rec.samples(), 5u);
  EXPECT_EQ(rec.t_begin(), 0.0);
  EXPECT_EQ(rec.t_end(), 0.05);
}

TEST_F(RecordingTest, CsvShuffledColumnsCommentsCrlfSpaces) {
  const std::string path = write("shuffled.csv",
                                 "# recorded by a test\r\n"
                                 "\r\n"
                                 " t , x,marker,Z,  y,X,z,Y\r\n"
                                 "0,0.1, m1 ,0.3,0.2,0.1,0.3,0.2\r\n"
                                 "# a comment between rows\r\n"
                                 "0,1,m2,0,0,1,0,0\r\n"
                                 "   \r\n"
                                 "0.013,0.11,m1,0.3,0.2,0.1,0.3,0.2\r\n"
                                 "0.02, 1.5 ,m2,0,0,1,-2e-3,0\r\n"
                                 "0.05,0.12,m1,0.3,0.21,0.1,0.3,0.2");  // no final newline
  const Recording rec = read_recording(path);
  Recording want = expected_positions();
  want.channels[0].line = {4, 8, 10};
  want.channels[1].line = {6, 9};
  expect_same(rec, want);
}

TEST_F(RecordingTest, CsvAccelerometers) {
  const std::string path = write("acc.csv",
                                 "sensor,X,Y,Z,t,ax,ay,az\n"
                                 "s7,0,0,1,0,0,0,-9.81\n"
                                 "s7,0,0,1,0.001,0.5,0,-9.81\n"
                                 "s7,0,0,1,0.0025,1e3,-1e-3,-9.81\n");
  const Recording rec = read_recording(path);
  ASSERT_EQ(rec.channels.size(), 1u);
  const Channel& c = rec.channels[0];
  EXPECT_EQ(c.id, "s7");
  EXPECT_EQ(c.kind, ChannelKind::Acceleration);
  EXPECT_EQ(c.X, (std::array<double, 3>{0, 0, 1}));
  EXPECT_EQ(c.t, (std::vector<double>{0, 0.001, 0.0025}));
  EXPECT_EQ(c.value[2], (std::array<double, 3>{1e3, -1e-3, -9.81}));
  EXPECT_EQ(c.line, (std::vector<long>{2, 3, 4}));
}

TEST_F(RecordingTest, WriteCsvRoundTripBothKinds) {
  Recording rec = expected_positions();
  for (Channel& c : rec.channels) c.line.clear();
  rec.channels[0].value[1] = {1.0 / 3.0, -2.5e10, 1e-300};
  rec.channels[1].t = {0.1, 0.1 + 1e-15};
  Channel s;
  s.id = "acc 1";  // inner spaces survive
  s.kind = ChannelKind::Acceleration;
  s.X = {-0.5, 0.25, 1.0 / 7.0};
  s.t = {0, 0.001, 0.002};
  s.value = {{0, 0, -9.81}, {std::nextafter(1.0, 2.0), 0, -9.81}, {4.9e-324, 0, -9.81}};
  rec.channels.push_back(s);

  const std::string path = dir + "/out.csv";
  write_recording_csv(rec, path);
  EXPECT_EQ(acceleration_csv_path(path), dir + "/out-acc.csv");
  EXPECT_EQ(acceleration_csv_path("rec"), "rec-acc");
  ASSERT_TRUE(fs::exists(dir + "/out-acc.csv"));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 2)
      << "temporary files left behind";

  Recording back = read_recording(path);
  merge_recordings(back, read_recording(dir + "/out-acc.csv"));
  expect_same(back, rec, false);
  EXPECT_EQ(back.source, path + ", " + dir + "/out-acc.csv");
  EXPECT_EQ(back.channels[2].file, dir + "/out-acc.csv");
  EXPECT_EQ(back.samples(), 8u);
  EXPECT_EQ(back.t_begin(), 0.0);
  EXPECT_EQ(back.t_end(), 0.1 + 1e-15);
}

TEST_F(RecordingTest, WriteCsvPositionsOnlyWritesOneFile) {
  write_recording_csv(expected_positions(), dir + "/p.csv");
  EXPECT_TRUE(fs::exists(dir + "/p.csv"));
  EXPECT_FALSE(fs::exists(dir + "/p-acc.csv"));
  expect_same(read_recording(dir + "/p.csv"), expected_positions(), false);
}

TEST_F(RecordingTest, LargeCsvReads) {
  const int markers = 10, steps = 10000;
  Recording rec;
  for (int m = 0; m < markers; ++m) {
    Channel c;
    c.id = "marker" + std::to_string(m);
    c.X = {0.01 * m, 0.5, -0.25};
    for (int s = 0; s < steps; ++s) {
      c.t.push_back(1e-4 * s);
      c.value.push_back({c.X[0] + 1e-3 * std::sin(0.01 * s), 0.5, -0.25 + 1e-6 * s});
    }
    rec.channels.push_back(c);
  }
  write_recording_csv(rec, dir + "/large.csv");
  const Recording back = read_recording(dir + "/large.csv");
  EXPECT_EQ(back.samples(), static_cast<std::size_t>(markers * steps));
  expect_same(back, rec, false);
}

TEST_F(RecordingTest, Hdf5IntegerIdsAtRoot) {
  const std::string path = dir + "/int.h5";
  {
    H5Writer h(path);
    h.ints("marker", {3, 5, 3, 5, 3});
    h.numbers("X", {0.1, 1, 0.1, 1, 0.1});
    h.numbers("Y", {0.2, 0, 0.2, 0, 0.2});
    h.numbers("Z", {0.3, 0, 0.3, 0, 0.3});
    h.numbers("t", {0, 0, 0.013, 0.02, 0.05});
    h.numbers("x", {0.5, 1, 0.25, 1.5, 0.125}, H5T_IEEE_F32LE);  // float32 accepted
    h.numbers("y", {0.2, 0, 0.2, 0, 0.21});
    h.numbers("z", {0.3, 0, 0.3, -2e-3, 0.3});
  }
  const Recording rec = read_recording(path);
  ASSERT_EQ(rec.channels.size(), 2u);
  EXPECT_EQ(rec.channels[0].id, "3");
  EXPECT_EQ(rec.channels[1].id, "5");
  EXPECT_EQ(rec.channels[0].kind, ChannelKind::Position);
  EXPECT_EQ(rec.channels[0].X, (std::array<double, 3>{0.1, 0.2, 0.3}));
  EXPECT_EQ(rec.channels[0].t, (std::vector<double>{0, 0.013, 0.05}));
  EXPECT_EQ(rec.channels[0].value[2], (std::array<double, 3>{0.125, 0.21, 0.3}));
  EXPECT_EQ(rec.channels[1].value[1], (std::array<double, 3>{1.5, 0, -2e-3}));
  EXPECT_EQ(rec.channels[0].line, (std::vector<long>{0, 2, 4}));
  EXPECT_EQ(rec.channels[1].line, (std::vector<long>{1, 3}));
}

TEST_F(RecordingTest, Hdf5StringIdsVariableAndFixed) {
  Recording want = expected_positions();
  for (Channel& c : want.channels) c.line.clear();
  want.channels[0].line = {0, 2, 4};
  want.channels[1].line = {1, 3};
  for (bool fixed : {false, true}) {
    const std::string path = dir + (fixed ? "/fixed.h5" : "/vlen.h5");
    {
      H5Writer h(path);
      const std::vector<std::string> ids{"m1", "m2", "m1", "m2", "m1"};
      if (fixed) {
        h.fixed_strings("marker", ids, 8);
      } else {
        h.vlen_strings("marker", ids);
      }
      h.numbers("X", {0.1, 1, 0.1, 1, 0.1});
      h.numbers("Y", {0.2, 0, 0.2, 0, 0.2});
      h.numbers("Z", {0.3, 0, 0.3, 0, 0.3});
      h.numbers("t", {0, 0, 0.013, 0.02, 0.05});
      h.numbers("x", {0.1, 1, 0.11, 1.5, 0.12});
      h.numbers("y", {0.2, 0, 0.2, 0, 0.21});
      h.numbers("z", {0.3, 0, 0.3, -2e-3, 0.3});
    }
    SCOPED_TRACE(path);
    expect_same(read_recording(path), want);
  }
}

TEST_F(RecordingTest, Hdf5BothKindsInGroups) {
  const std::string path = dir + "/both.hdf5";
  {
    H5Writer h(path);
    h.group("positions");
    h.vlen_strings("positions/marker", {"m1", "m1"});
    h.numbers("positions/X", {0.1, 0.1});
    h.numbers("positions/Y", {0.2, 0.2});
    h.numbers("positions/Z", {0.3, 0.3});
    h.numbers("positions/t", {0, 0.5});
    h.numbers("positions/x", {0.1, 0.15});
    h.numbers("positions/y", {0.2, 0.2});
    h.numbers("positions/z", {0.3, 0.3});
    h.group("accelerations");
    h.ints("accelerations/sensor", {1, 1, 1});
    h.numbers("accelerations/X", {0, 0, 0});
    h.numbers("accelerations/Y", {0, 0, 0});
    h.numbers("accelerations/Z", {1, 1, 1});
    h.numbers("accelerations/t", {0, 0.25, 0.5});
    h.numbers("accelerations/ax", {0, 0.5, 1});
    h.numbers("accelerations/ay", {0, 0, 0});
    h.numbers("accelerations/az", {-9.81, -9.81, -9.81});
  }
  const Recording rec = read_recording(path);
  ASSERT_EQ(rec.channels.size(), 2u);
  EXPECT_EQ(rec.channels[0].id, "m1");
  EXPECT_EQ(rec.channels[0].kind, ChannelKind::Position);
  EXPECT_EQ(rec.channels[0].value[1], (std::array<double, 3>{0.15, 0.2, 0.3}));
  EXPECT_EQ(rec.channels[1].id, "1");
  EXPECT_EQ(rec.channels[1].kind, ChannelKind::Acceleration);
  EXPECT_EQ(rec.channels[1].t, (std::vector<double>{0, 0.25, 0.5}));
  EXPECT_EQ(rec.channels[1].value[1], (std::array<double, 3>{0.5, 0, -9.81}));
  EXPECT_EQ(rec.samples(), 5u);
}

TEST_F(RecordingTest, MergeAllowsOneIdInBothKindsRejectsDuplicates) {
  const std::string pos = write("pos.csv", kPositionsCsv);
  const std::string acc = write("acc.csv",
                                "sensor,X,Y,Z,t,ax,ay,az\n"
                                "m1,0,0,1,0,0,0,-9.81\n"
                                "m1,0,0,1,0.001,0.5,0,-9.81\n");
  Recording rec = read_recording(pos);
  merge_recordings(rec, read_recording(acc));
  EXPECT_EQ(rec.channels.size(), 3u);
  expect_input_error([&] { merge_recordings(rec, read_recording(acc)); },
                     {"acc.csv", "sensor 'm1'", "already in"});
  EXPECT_EQ(rec.channels.size(), 3u) << "a failed merge must leave the recording unchanged";
}

// -------------------------------------------------------------------------------- bad files

TEST_F(RecordingTest, MissingColumn) {
  // A value column may be left out (not measured); the id, reference point and time may not.
  const std::string path = write("missing.csv", "marker,X,Y,t,x,y,z\nm1,0,0,0,0,0,0\n");
  expect_input_error([&] { read_recording(path); }, {"missing.csv:1:", "missing column 'Z'"});
}

TEST_F(RecordingTest, UnknownColumn) {
  const std::string path = write("unknown.csv", "marker,X,Y,Z,t,x,y,z,w\n");
  expect_input_error([&] { read_recording(path); }, {"unknown.csv:1:", "unknown column 'w'"});
}

TEST_F(RecordingTest, DuplicateColumn) {
  const std::string path = write("dup.csv", "marker,X,Y,Z,t,x,y,z, t\n");
  expect_input_error([&] { read_recording(path); }, {"dup.csv:1:", "duplicate column 't'"});
}

TEST_F(RecordingTest, ShortRow) {
  const std::string path = positions_with("short.csv", 4, "m1,0.1,0.2,0.3,0.013,0.11,0.2");
  expect_input_error([&] { read_recording(path); }, {"short.csv:4:", "expected 8 fields, got 7"});
}

TEST_F(RecordingTest, NonNumericField) {
  const std::string path = positions_with("text.csv", 5, "m2,1,0,0,0.02,1.5abc,0,0");
  expect_input_error([&] { read_recording(path); },
                     {"text.csv:5:", "column 'x'", "'1.5abc' is not a number"});
  const std::string empty = positions_with("empty_field.csv", 3, "m2,1,,0,0,1,0,0");
  expect_input_error([&] { read_recording(empty); },
                     {"empty_field.csv:3:", "column 'Y'", "is not a number"});
}

TEST_F(RecordingTest, NaNValue) {
  const std::string path = positions_with("nan.csv", 6, "m1,0.1,0.2,0.3,0.05,0.12,NaN,0.3");
  expect_input_error([&] { read_recording(path); }, {"nan.csv:6:", "column 'y'", "not finite"});
}

TEST_F(RecordingTest, InfValue) {
  const std::string path = positions_with("inf.csv", 2, "m1,0.1,0.2,0.3,-inf,0.1,0.2,0.3");
  expect_input_error([&] { read_recording(path); }, {"inf.csv:2:", "column 't'", "not finite"});
  const std::string huge = positions_with("huge.csv", 3, "m2,1e999,0,0,0,1,0,0");
  expect_input_error([&] { read_recording(huge); }, {"huge.csv:3:", "column 'X'", "not finite"});
}

TEST_F(RecordingTest, TimeGoesBackwards) {
  const std::string path = positions_with("back.csv", 6, "m1,0.1,0.2,0.3,0.01,0.12,0.21,0.3");
  expect_input_error([&] { read_recording(path); },
                     {"back.csv:6:", "time goes backwards at line 6 for marker 'm1'",
                      "t=0.01 after t=0.013 (line 4)"});
}

TEST_F(RecordingTest, TimeRepeats) {
  const std::string path = positions_with("repeat.csv", 5, "m2,1,0,0,0,1.5,0,0");
  expect_input_error(
      [&] { read_recording(path); },
      {"repeat.csv:5:", "time repeats at line 5 for marker 'm2'", "t=0 after t=0 (line 3)"});
}

TEST_F(RecordingTest, ReferencePointChangesWithinMarker) {
  const std::string path = positions_with("moved.csv", 6, "m1,0.1,0.2,0.31,0.05,0.12,0.21,0.3");
  expect_input_error([&] { read_recording(path); },
                     {"moved.csv:6:", "column 'Z'", "marker 'm1'", "changes", "line 2"});
  // Within the tolerance (1e-12 relative) the reference point is the same.
  const std::string close =
      positions_with("close.csv", 4, "m1,0.1,0.2,0.3000000000000001,0.013,0,0,0");
  EXPECT_NO_THROW(read_recording(close));
}

TEST_F(RecordingTest, SingleSampleMarker) {
  const std::string path = positions_with("single.csv", 5, "# m2's second sample removed");
  expect_input_error([&] { read_recording(path); },
                     {"single.csv:3:", "marker 'm2' has only 1 sample", "at least 2"});
}

TEST_F(RecordingTest, EmptyFile) {
  const std::string path = write("empty.csv", "");
  expect_input_error([&] { read_recording(path); }, {"empty.csv", "empty file"});
  const std::string comments = write("comments.csv", "# nothing\n\n");
  expect_input_error([&] { read_recording(comments); }, {"comments.csv", "empty file"});
}

TEST_F(RecordingTest, HeaderOnly) {
  const std::string path = write("header.csv", "# comment\nmarker,X,Y,Z,t,x,y,z\n\n# more\n");
  expect_input_error([&] { read_recording(path); },
                     {"header.csv:2:", "no data rows after the header"});
}

TEST_F(RecordingTest, MissingFile) {
  expect_input_error([&] { read_recording(dir + "/absent.csv"); },
                     {dir + "/absent.csv", "no such file"});
  expect_input_error([&] { read_recording(dir + "/absent.h5"); },
                     {dir + "/absent.h5", "no such file"});
}

TEST_F(RecordingTest, Hdf5MissingDataset) {
  const std::string path = dir + "/nodata.h5";
  {
    H5Writer h(path);
    h.ints("sensor", {1, 1});
    for (const char* n : {"X", "Y", "Z", "ax", "ay", "az"}) h.numbers(n, {0, 1});
  }
  expect_input_error([&] { read_recording(path); }, {"nodata.h5", "missing dataset /t"});
}

TEST_F(RecordingTest, Hdf5LengthMismatch) {
  const std::string path = dir + "/length.h5";
  {
    H5Writer h(path);
    h.group("positions");
    h.ints("positions/marker", {1, 1, 1});
    for (const char* n : {"X", "Y", "Z", "t", "x", "z"}) {
      h.numbers(std::string("positions/") + n, {0, 1, 2});
    }
    h.numbers("positions/y", {0, 1});
  }
  expect_input_error([&] { read_recording(path); },
                     {"length.h5", "length mismatch", "dataset /positions/y has 2 rows",
                      "/positions/marker has 3"});
}

TEST_F(RecordingTest, Hdf5BadRowsNameDatasetAndRow) {
  const std::string path = dir + "/rows.h5";
  {
    H5Writer h(path);
    h.vlen_strings("marker", {"a", "a", "a"});
    for (const char* n : {"X", "Y", "Z", "x", "y", "z"}) h.numbers(n, {0, 0, 0});
    h.numbers("t", {0, 1, 0.5});
  }
  expect_input_error(
      [&] { read_recording(path); },
      {"rows.h5", "dataset /t row 2", "time goes backwards at row 2", "marker 'a'", "(row 1)"});
}

TEST_F(RecordingTest, Hdf5NonNumericDataset) {
  const std::string path = dir + "/text.h5";
  {
    H5Writer h(path);
    h.ints("marker", {1, 1});
    h.vlen_strings("X", {"0", "0"});
    for (const char* n : {"Y", "Z", "t", "x", "y", "z"}) h.numbers(n, {0, 1});
  }
  expect_input_error([&] { read_recording(path); }, {"text.h5", "dataset /X", "not numeric"});
}

TEST_F(RecordingTest, CheckAttachedRejectsMarkerOutsideBox) {
  const std::string path = write("pos.csv", kPositionsCsv);
  const Recording rec = read_recording(path);
  // A box [0, 0.5]^3 holds m1's reference point (0.1, 0.2, 0.3) but not m2's (1, 0, 0).
  auto box = [](const std::array<double, 3>& p) {
    for (double c : p) {
      if (c < 0 || c > 0.5) return false;
    }
    return true;
  };
  expect_input_error([&] { check_attached(rec, box); },
                     {"pos.csv:3:", "marker 'm2'", "not inside the body"});
  EXPECT_NO_THROW(check_attached(rec, [](const std::array<double, 3>&) { return true; }));
}

}  // namespace
}  // namespace gen4d::diagnose
