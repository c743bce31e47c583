// Recordings that measure some values only (empty CSV cells, column subsets, NaN or missing
// HDF5 datasets, --unmeasured), how gen4d diagnose uses them (never scored, noise estimated
// without them), recordings that start mid-motion, and sensors on the body's surface.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <mpi.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "core/Deck.hpp"
#include "diagnose/Pipeline.hpp"
#include "test_diagnose_common.hpp"

using namespace gen4d;
using namespace gen4d::diagnose;
using namespace gen4d::diagnose::testing;

namespace {

namespace fs = std::filesystem;

//! A folder of its own per rank count; `write` puts a file there.
class PartialRecording : public ::testing::Test {
 protected:
  void SetUp() override {
    int size = 1, rank = 0;
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    dir = "recording_partial_np" + std::to_string(size) + "_rank" + std::to_string(rank);
    fs::create_directories(dir);
  }
  std::string write(const std::string& name, const std::string& text) const {
    const std::string path = dir + "/" + name;
    std::ofstream(path) << text;
    return path;
  }
  std::string dir;
};

using Mask = std::array<bool, 3>;

//! The InputError message of read_recording(path, opt) (a failure when it reads).
std::string read_error(const std::string& path, const ReadOptions& opt = {}) {
  return refusal([&] { read_recording(path, opt); }, path);
}

void expect_contains(const std::string& text, const std::vector<std::string>& parts) {
  for (const auto& p : parts) EXPECT_NE(text.find(p), std::string::npos) << p << " in: " << text;
  EXPECT_EQ(text.find('\n'), std::string::npos) << "one line: " << text;
}

// ------------------------------------------------------------------------------- reading

TEST_F(PartialRecording, EmptyCellsAreNotMeasured) {
  const std::string path = write("cells.csv",
                                 "sensor,X,Y,Z,t,ax,ay,az\n"
                                 "1,0.44,0.0254,0.002,0.000,,,-3.2\n"
                                 "1,0.44,0.0254,0.002,0.002, ,,-3.1\n"
                                 "1,0.44,0.0254,0.002,0.004,,,\n"  // nothing measured: skipped
                                 "2,0.10,0.0254,0.002,0.000,1,2,3\n"
                                 "1,0.44,0.0254,0.002,0.006,0.5,,-3.0\n"
                                 "2,0.10,0.0254,0.002,0.002,4,5,6\n");
  const Recording rec = read_recording(path);
  ASSERT_EQ(rec.channels.size(), 2u);
  const Channel& a = rec.channels[0];
  EXPECT_EQ(a.id, "1");
  ASSERT_EQ(a.t.size(), 3u);
  EXPECT_EQ(a.t[2], 0.006);
  EXPECT_EQ(a.line, (std::vector<long>{2, 3, 6}));
  ASSERT_EQ(a.measured.size(), 3u);
  EXPECT_EQ(a.measured[0], (Mask{false, false, true}));
  EXPECT_EQ(a.measured[2], (Mask{true, false, true}));
  EXPECT_EQ(a.value[0][2], -3.2);
  EXPECT_EQ(a.value[0][0], 0.0);  // not measured: 0, never read
  EXPECT_EQ(a.value[2][0], 0.5);
  EXPECT_FALSE(a.has(1, 0));
  EXPECT_TRUE(a.has(1, 2));
  // A channel whose every value is measured keeps no mask.
  EXPECT_TRUE(rec.channels[1].measured.empty());
  EXPECT_TRUE(rec.channels[1].has(1, 1));
}

TEST_F(PartialRecording, ColumnSubsets) {
  const Recording acc = read_recording(write("az.csv",
                                             "sensor,X,Y,Z,t,az\n"
                                             "s,0,0,0,0,1.5\n"
                                             "s,0,0,0,0.1,-1.5\n"));
  ASSERT_EQ(acc.channels.size(), 1u);
  EXPECT_EQ(acc.channels[0].kind, ChannelKind::Acceleration);
  for (const Mask& m : acc.channels[0].measured) EXPECT_EQ(m, (Mask{false, false, true}));
  EXPECT_EQ(acc.channels[0].value[1][2], -1.5);
  const Recording pos = read_recording(write("xz.csv",
                                             "t,marker,z,X,Y,Z,x\n"
                                             "0,m,0.3,0,0,0,0.1\n"
                                             "0.1,m,0.31,0,0,0,\n"));
  const Channel& m = pos.channels[0];
  EXPECT_EQ(m.kind, ChannelKind::Position);
  EXPECT_EQ(m.measured[0], (Mask{true, false, true}));
  EXPECT_EQ(m.measured[1], (Mask{false, false, true}));
  EXPECT_EQ(m.value[0][0], 0.1);
  EXPECT_EQ(m.value[1][2], 0.31);
}

TEST_F(PartialRecording, UnmeasuredColumnsIgnoreTheirValues) {
  // A file that writes 0 for the axes the sensor lacks reads, with --unmeasured, as the file
  // that leaves them out.
  const std::string zeros = write("zeros.csv",
                                  "sensor,X,Y,Z,t,ax,ay,az\n"
                                  "1,0.44,0.0254,0.002,0.000,0,0,-17.3\n"
                                  "1,0.44,0.0254,0.002,0.002,0,0,-17.6\n"
                                  "1,0.44,0.0254,0.002,0.004,0,0,-9.29\n");
  const std::string subset = write("subset.csv",
                                   "sensor,X,Y,Z,t,az\n"
                                   "1,0.44,0.0254,0.002,0.000,-17.3\n"
                                   "1,0.44,0.0254,0.002,0.002,-17.6\n"
                                   "1,0.44,0.0254,0.002,0.004,-9.29\n");
  ReadOptions opt;
  opt.unmeasured = {"ax", "ay", "x"};  // a position column: no effect on accelerometers
  const Recording a = read_recording(zeros, opt), b = read_recording(subset);
  ASSERT_EQ(a.channels.size(), 1u);
  EXPECT_EQ(a.channels[0].t, b.channels[0].t);
  EXPECT_EQ(a.channels[0].value, b.channels[0].value);
  EXPECT_EQ(a.channels[0].measured, b.channels[0].measured);
  // Without the option the zeros are values.
  EXPECT_TRUE(read_recording(zeros).channels[0].measured.empty());
  // Every value unmeasured: the sensor has no measured value.
  opt.unmeasured = {"az"};
  expect_contains(read_error(subset, opt), {"subset.csv:2:", "sensor '1' has no measured value"});
  // A name that is no value column.
  opt.unmeasured = {"ax", "Z"};
  expect_contains(read_error(zeros, opt), {"--unmeasured", "'Z' is not a value column"});
}

//! Writes 1-D datasets at the root of a new HDF5 file.
class H5File {
 public:
  explicit H5File(const std::string& path)
      : f_(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT)) {}
  ~H5File() { H5Fclose(f_); }
  H5File(const H5File&) = delete;
  H5File& operator=(const H5File&) = delete;
  void numbers(const char* name, const std::vector<double>& v) { put(name, H5T_NATIVE_DOUBLE, v); }
  void ints(const char* name, const std::vector<long long>& v) { put(name, H5T_NATIVE_LLONG, v); }

 private:
  template <class T>
  void put(const char* name, hid_t type, const std::vector<T>& v) {
    const hsize_t n = v.size();
    const hid_t space = H5Screate_simple(1, &n, nullptr);
    const hid_t ds = H5Dcreate2(f_, name, type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    H5Dwrite(ds, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data());
    H5Dclose(ds);
    H5Sclose(space);
  }
  hid_t f_;
};

TEST_F(PartialRecording, Hdf5NaNAndMissingDatasets) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::string path = dir + "/partial.h5";
  {
    H5File h(path);
    h.ints("marker", {7, 7, 7, 8, 8});
    h.numbers("X", {0, 0, 0, 1, 1});
    h.numbers("Y", {0, 0, 0, 0, 0});
    h.numbers("Z", {0, 0, 0, 0, 0});
    h.numbers("t", {0, 0.1, 0.2, 0, 0.1});
    h.numbers("x", {0.5, nan, nan, 1.0, 1.1});  // no dataset y
    h.numbers("z", {0.2, 0.3, nan, 0.0, 0.1});
  }
  const Recording rec = read_recording(path);
  ASSERT_EQ(rec.channels.size(), 2u);
  const Channel& a = rec.channels[0];
  ASSERT_EQ(a.t.size(), 2u) << "the row with nothing measured is skipped";
  EXPECT_EQ(a.measured[0], (Mask{true, false, true}));
  EXPECT_EQ(a.measured[1], (Mask{false, false, true}));
  EXPECT_EQ(a.value[1][2], 0.3);
  EXPECT_EQ(rec.channels[1].measured[1], (Mask{true, false, true}));
  // inf is still an error; NaN in a reference point or a time too.
  const std::string bad = dir + "/inf.h5";
  {
    H5File h(bad);
    h.ints("sensor", {1, 1});
    for (const char* n : {"X", "Y", "Z"}) h.numbers(n, {0, 0});
    h.numbers("t", {0, nan});
    h.numbers("az", {1, 2});
  }
  expect_contains(read_error(bad), {"inf.h5", "dataset /t row 1", "not finite"});
  const std::string none = dir + "/novalue.h5";
  {
    H5File h(none);
    h.ints("sensor", {1, 1});
    for (const char* n : {"X", "Y", "Z", "t"}) h.numbers(n, {0, 1});
  }
  expect_contains(read_error(none), {"novalue.h5", "missing datasets /ax, /ay, /az"});
}

TEST_F(PartialRecording, BadFilesNameFileLineAndChannel) {
  // A sensor none of whose rows measures anything.
  expect_contains(read_error(write("silent.csv",
                                   "sensor,X,Y,Z,t,ax,ay,az\n"
                                   "1,0,0,0,0,1,2,3\n"
                                   "1,0,0,0,1,1,2,3\n"
                                   "# quiet\n"
                                   "q,0,0,0,0,,,\n"
                                   "q,0,0,0,1,,,\n")),
                  {"silent.csv:5:", "sensor 'q' has no measured value"});
  // No value column at all.
  expect_contains(read_error(write("novalue.csv", "marker,X,Y,Z,t\nm,0,0,0,0\n")),
                  {"novalue.csv:1:", "no value column", "x, y, z"});
  // The id, reference point and time may not be empty.
  expect_contains(read_error(write("emptyt.csv", "marker,X,Y,Z,t,x\nm,0,0,0,,1\n")),
                  {"emptyt.csv:2:", "column 't'", "is not a number"});
  // A value that is written must be a finite number (an empty cell is "not measured").
  expect_contains(read_error(write("nan.csv", "sensor,X,Y,Z,t,az\n1,0,0,0,0,NaN\n")),
                  {"nan.csv:2:", "column 'az'", "not finite"});
  expect_contains(read_error(write("text.csv", "sensor,X,Y,Z,t,az,ax\n1,0,0,0,0,2,abc\n")),
                  {"text.csv:2:", "column 'ax'", "'abc' is not a number"});
  // Time order is checked on the samples kept.
  expect_contains(read_error(write("back.csv",
                                   "marker,X,Y,Z,t,z\n"
                                   "m,0,0,0,0.2,1\n"
                                   "m,0,0,0,0.3,\n"
                                   "m,0,0,0,0.1,1\n")),
                  {"back.csv:4:", "time goes backwards", "marker 'm'"});
}

TEST_F(PartialRecording, WritesEmptyCells) {
  Recording rec;
  Channel c;
  c.id = "s1";
  c.kind = ChannelKind::Acceleration;
  c.X = {0.1, 0.2, 0.3};
  c.t = {0, 0.5, 1.0, 1.5};
  c.value = {{1, 0, 2}, {0, 0, 0}, {0.25, -1, 0}, {3, 4, 5}};
  c.measured = {Mask{true, false, true}, Mask{false, false, false}, Mask{true, true, false},
                Mask{true, true, true}};
  rec.channels.push_back(c);
  const std::string path = dir + "/written.csv";
  write_recording_csv(rec, path);
  const std::string acc = acceleration_csv_path(path);
  std::ifstream in(acc);
  std::string header, row;
  std::getline(in, header);
  std::getline(in, row);
  EXPECT_EQ(header, "sensor,X,Y,Z,t,ax,ay,az");
  EXPECT_EQ(row, "s1,0.1,0.2,0.3,0,1,,2");
  const Recording back = read_recording(acc);
  ASSERT_EQ(back.channels.size(), 1u);
  const Channel& b = back.channels[0];
  // The sample with nothing measured is left out; the others come back exactly.
  EXPECT_EQ(b.t, (std::vector<double>{0, 1.0, 1.5}));
  EXPECT_EQ(b.measured, (std::vector<Mask>{c.measured[0], c.measured[2], c.measured[3]}));
  EXPECT_EQ(b.value, (std::vector<std::array<double, 3>>{c.value[0], c.value[2], c.value[3]}));
}

// ------------------------------------------------------------------------------- noise

//! A sensor at 500 Hz: a 12 Hz ring-down along z plus noise `sd` on z; x and y read 0, or are
//! left out (`partial`).
Channel ring_down(bool partial, double sd) {
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0, sd);
  Channel c;
  c.kind = ChannelKind::Acceleration;
  c.id = "1";
  for (int k = 0; k < 3000; ++k) {
    const double t = 0.002 * k;
    c.t.push_back(t);
    c.value.push_back({0, 0, 20 * std::exp(-0.3 * t) * std::cos(2 * kPi * 12 * t) + noise(rng)});
    if (partial) c.measured.push_back({false, false, true});
  }
  return c;
}

TEST(PartialRecordingNoise, SkipsValuesNotMeasured) {
  // Zeros written for the missing axes are two thirds of the blocks: the median noise is 0.
  const Channel zeros = ring_down(false, 0.01), partial = ring_down(true, 0.01);
  EXPECT_LT(estimate_noise({&zeros}), 1e-12);
  EXPECT_NEAR(estimate_noise({&partial}), 0.01, 0.002);
  // A mask that says every value is measured changes nothing, bit for bit.
  Channel all = zeros;
  all.measured.assign(all.t.size(), {true, true, true});
  Channel m1 = partial;
  m1.measured.clear();
  for (auto& v : m1.value) v = {v[2], v[2] * 0.5, -v[2]};
  Channel m2 = m1;
  m2.measured.assign(m2.t.size(), {true, true, true});
  EXPECT_EQ(estimate_noise({&m1}), estimate_noise({&m2}));
  EXPECT_EQ(estimate_noise({&zeros}), estimate_noise({&all}));
}

TEST(PartialRecordingNoise, RealStripRecording) {
  // The plucked aluminium strip: a single-axis accelerometer whose ax, ay are written as 0.
  const std::string path =
      std::string(GEN4D_SHARED_DIR) + "/data/recordings/strip_plain/recording.csv";
  if (!fs::exists(path)) GTEST_SKIP() << path << " is not here";
  ReadOptions opt;
  opt.unmeasured = {"ax", "ay"};
  const Recording rec = read_recording(path, opt);
  ASSERT_EQ(rec.channels.size(), 1u);
  const Channel& c = rec.channels[0];
  EXPECT_EQ(c.t.size(), 3000u);
  EXPECT_EQ(c.t.front(), 0.0);
  ASSERT_EQ(c.measured.size(), 3000u);
  for (const Mask& m : c.measured) ASSERT_EQ(m, (Mask{false, false, true}));
  // Its noise, stated as about 0.01 m/s^2 rms, is measured from az alone; with the zeros
  // counted as values the estimate collapses to 0.
  const double sd = estimate_noise({&c});
  EXPECT_GT(sd, 0.003);
  EXPECT_LT(sd, 0.03);
  const Recording raw = read_recording(path);
  EXPECT_LT(estimate_noise({&raw.channels[0]}), 0.1 * sd);
}

// ------------------------------------------------------------------------------- sensors

TEST_F(PartialRecording, SensorsOnTheSurfaceAttachOutsideAreRefused) {
  // A strip 0.2 x 0.05 x 0.004 m on cells of 0.01 x 0.01 x 0.002 m.
  const std::string deck = test::TestDeck()
                               .simulation(1e-3, 0.01, {{"gravity", "[0, 0, 0]"}})
                               .table("domain", {{"voxel_size", "[0.01, 0.01, 0.002]"}})
                               .box({0, 0, 0}, {0.2, 0.05, 0.004})
                               .material(7e10, 0.33, 2700)
                               .clamp();
  const Config cfg = parse_deck(deck, "strip.toml", ".");
  const VoxelModel m(cfg);
  const std::string path = write("surface.csv",
                                 "sensor,X,Y,Z,t,az\n"
                                 "top,0.176,0.0254,0.004,0,1\n"
                                 "top,0.176,0.0254,0.004,0.001,1\n"
                                 "corner,0.2,0.05,0.004,0,1\n"
                                 "corner,0.2,0.05,0.004,0.001,1\n"
                                 "off,0.176,0.0254,0.0055,0,1\n"
                                 "off,0.176,0.0254,0.0055,0.001,1\n");
  Recording rec = read_recording(path);
  auto inside = [&](const std::array<double, 3>& X) { return m.inside(X); };
  expect_contains(refusal([&] { check_attached(rec, inside); }, "a sensor above the strip"),
                  {"surface.csv:6:", "sensor 'off'", "is not inside the body"});
  rec.channels.pop_back();
  EXPECT_NO_THROW(check_attached(rec, inside));
  // On the face: interpolated in a top-layer voxel from its top face's nodes alone; the corner
  // point from the corner node.
  for (const Channel& c : rec.channels) {
    const Attachment at = m.attach(c.X);
    double sum = 0, top = 0;
    for (int l = 0; l < 8; ++l) sum += at.w[l], top += ((l >> 2) & 1) ? at.w[l] : 0.0;
    EXPECT_NEAR(sum, 1.0, 1e-12) << c.id;
    EXPECT_NEAR(top, 1.0, 1e-12) << c.id;
  }
  EXPECT_NEAR(m.attach(rec.channels[1].X).w[7], 1.0, 1e-12);
}

// ------------------------------------------------------------------------------- diagnosis

//! The tiny cantilever of the stage tests (8x2x2 voxels), E 15 % above the deck's, gravity and
//! a pulse.
const std::string kDeck = cantilever(named("partial-beam", -9.81), 0.004, 0.6, {0.08, 0.02, 0.02},
                                     3e5, 0.075, pulse({0, 0.01, -0.01}, 0.1));
constexpr double kTrueE = 3e5 * 1.15, kNoise = 2e-5;

Config deck() {
  return parse_deck(kDeck, "<partial deck>", ".");
}

//! The recording of the truth (4 markers, every 5 ms, noise `sd`).
Recording truth_recording(double sd = kNoise) {
  const VoxelModel m(deck());
  Physics truth = m.nominal();
  truth.youngs_modulus = kTrueE;
  const std::vector<Vec3d> markers = {
      {0.08, 0.01, 0.02}, {0.06, 0.0, 0.01}, {0.04, 0.02, 0.0}, {0.08, 0.0, 0.0}};
  const auto req = marker_requests(m, markers, 120, 0.005);
  const Trace tr = m.run(truth, req);
  EXPECT_TRUE(tr.ok) << tr.failure;
  return noisy_markers(markers, req, tr, sd, 5);
}

//! Writes `rec` under `name` (rank 0) and runs the stages observe and calibrate on it.
struct Calibrated {
  Config cfg = deck();
  DiagnoseOptions opt;
  std::unique_ptr<State> s;
  Calibrated(const Recording& rec, const std::string& name,
             const std::vector<std::string>& unmeasured = {}, bool hold_poisson = false) {
    int size = 1;
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    const std::string dir = "recording_partial_np" + std::to_string(size) + "/" + name;
    write_fresh_recording(rec, dir);
    opt.recordings = {dir + "/rec.csv"};
    opt.out_dir = dir + "/out";
    opt.effects = {"damping"};
    opt.refinement_check = false;
    opt.unmeasured = unmeasured;
    opt.hold_poisson = hold_poisson;
    s = std::make_unique<State>(MPI_COMM_WORLD, cfg, opt);
    observe(*s);
    calibrate(*s);
  }
};

TEST(PartialRecordingDiagnosis, AnAxisNotMeasuredCalibratesTheSameE) {
  const Recording full = truth_recording();
  Recording no_x = full;  // the x axis not measured: empty cells
  for (Channel& c : no_x.channels) c.measured.assign(c.t.size(), {false, true, true});
  Recording zeros_x = no_x;  // written as 0, declared by --unmeasured
  for (Channel& c : zeros_x.channels) {
    c.measured.clear();
    for (auto& v : c.value) v[0] = 0;
  }
  const Calibrated a(full, "full"), b(no_x, "no_x"), z(zeros_x, "zeros_x", {"x"});
  // x values are never observed: two values per sample, none of component 0.
  ASSERT_EQ(b.s->obs.size(), 2 * a.s->obs.size() / 3);
  for (int comp : b.s->obs.component) ASSERT_NE(comp, 0);
  ASSERT_EQ(b.s->obs.measured.size(), 4u);
  // The model's prediction at the measured values is the full one's at the same values.
  for (std::size_t i = 0, j = 0; i < a.s->obs.size(); ++i) {
    if (a.s->obs.component[i] == 0) continue;
    ASSERT_EQ(a.s->nominal_pred.y[i], b.s->nominal_pred.y[j]) << i;
    ASSERT_EQ(a.s->obs.y[i], b.s->obs.y[j]) << i;
    ++j;
  }
  // Runs cut at a horizon (the continuation fits' windows) keep the layout: NaN after it.
  Evaluator& ev = *b.s->ev;
  ev.set_horizon(0.3);
  const Prediction cut = ev.run_one(b.s->model->nominal());
  ev.set_horizon(std::numeric_limits<double>::infinity());
  ASSERT_TRUE(cut.ok);
  ASSERT_EQ(cut.y.size(), b.s->obs.size());
  for (std::size_t j = 0; j < cut.y.size(); ++j) {
    if (b.s->obs.t[j] <= 0.3)
      ASSERT_EQ(cut.y[j], b.s->nominal_pred.y[j]) << j;
    else
      ASSERT_TRUE(std::isnan(cut.y[j])) << j;
  }
  // The noise is estimated on the measured components alone.
  EXPECT_NEAR(b.s->D.noise_position, kNoise, kNoise / 3);
  // Both calibrate E to the truth, and to each other within the noise (y and z carry the
  // bending, x little of it); --unmeasured with zeros is the same diagnosis, bit for bit.
  const double Ea = a.s->D.youngs_modulus, Eb = b.s->D.youngs_modulus;
  EXPECT_NEAR(Ea / kTrueE, 1.0, 0.01);
  EXPECT_NEAR(Eb / kTrueE, 1.0, 0.01);
  EXPECT_NEAR(Eb / Ea, 1.0, 0.005);
  EXPECT_EQ(z.s->D.youngs_modulus, Eb);
  EXPECT_EQ(z.s->obs.y, b.s->obs.y);
  EXPECT_EQ(z.s->D.noise_position, b.s->D.noise_position);
}

TEST(PartialRecordingDiagnosis, HoldPoissonFitsEAlone) {
  // One marker's y alone (the bending direction under gravity and the pulse): one series sees
  // no lateral contraction, which the report says; --hold-poisson keeps nu at the deck's and
  // fits E alone (the truth has the deck's nu).
  const Recording full = truth_recording();
  Recording one = full;
  one.channels.resize(1);
  for (Channel& c : one.channels) c.measured.assign(c.t.size(), {false, true, false});
  const Calibrated a(full, "all_series"), b(one, "one_series");
  const Calibrated h(one, "one_series_held", {}, true);
  EXPECT_FALSE(a.s->D.one_series);
  EXPECT_TRUE(b.s->D.one_series);
  EXPECT_FALSE(b.s->D.poisson_held);
  EXPECT_TRUE(h.s->D.poisson_held);
  EXPECT_EQ(h.s->D.poisson_ratio, h.s->nominal.poisson_ratio);
  EXPECT_EQ(h.s->calibrated.poisson_ratio, h.s->nominal.poisson_ratio);
  EXPECT_NEAR(h.s->D.youngs_modulus / kTrueE, 1.0, 0.01);
}

TEST(PartialRecordingDiagnosis, ARecordingThatStartsMidMotion) {
  // The samples before t = 0.2 s (the pulse ended at 0.1 s) are lost: the model still runs
  // from the deck's t = 0 and is sampled at the recording's own times. (Noise 2.5 kNoise: the
  // deck's own dt/2 difference stays below the numerical check's threshold, so both keep dt.)
  const Recording full = truth_recording(2.5 * kNoise);
  Recording late = full;
  for (Channel& c : late.channels) {
    std::size_t k = 0;
    while (c.t[k] < 0.2 - 1e-12) ++k;
    c.t.erase(c.t.begin(), c.t.begin() + static_cast<long>(k));
    c.value.erase(c.value.begin(), c.value.begin() + static_cast<long>(k));
  }
  const Calibrated a(full, "from0"), b(late, "from02");
  EXPECT_NEAR(b.s->rec.t_begin(), 0.2, 1e-12);
  EXPECT_NEAR(b.s->obs.t.front(), 0.2, 1e-12);
  // The deck's prediction at t >= 0.2 is the full recording's, value for value.
  const std::size_t offset = a.s->obs.size() - b.s->obs.size();
  ASSERT_EQ(offset % 12, 0u);  // whole samples of the 4 markers' 3 values
  std::size_t j = 0;
  for (std::size_t i = 0; i < a.s->obs.size(); ++i) {
    if (a.s->obs.t[i] < 0.2 - 1e-12) continue;
    ASSERT_EQ(a.s->nominal_pred.y[i], b.s->nominal_pred.y[j]) << i;
    ++j;
  }
  EXPECT_EQ(j, b.s->obs.size());
  // E is calibrated from the free ring-down alone.
  EXPECT_NEAR(b.s->D.youngs_modulus / kTrueE, 1.0, 0.01);
}

}  // namespace
