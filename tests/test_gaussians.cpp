// Splat core: the 3DGS PLY reader and writer, covariances and kinematics under a deformation,
// splat objects of a deck (placement, splats of any shape, the solid a splat object occupies).
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Dense>

#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>

#include "core/Error.hpp"
#include "gaussians/DeckSplats.hpp"
#include "gaussians/Kinematics.hpp"
#include "gaussians/Ply.hpp"
#include "gaussians/SphericalHarmonics.hpp"
#include "gaussians/Splats.hpp"
#include "geometry/Shape.hpp"

namespace fs = std::filesystem;
using namespace gen4d::gaussians;
using gen4d::InputError;
using gen4d::RuntimeError;
using Mat3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kC0 = 0.28209479177387814;

std::string donut_path() {
  return (fs::path(GEN4D_SHARED_DIR) / "data" / "splats" / "donut" / "point_cloud.ply").string();
}

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::array<double, 9> to_array(const Mat3& m) {
  std::array<double, 9> a;
  Eigen::Map<Mat3>(a.data()) = m;
  return a;
}

Mat3 to_mat(const std::array<double, 9>& a) {
  return Eigen::Map<const Mat3>(a.data());
}

Mat3 sym(const std::array<double, 6>& a) {
  Mat3 m;
  m << a[0], a[1], a[2], a[1], a[3], a[4], a[2], a[4], a[5];
  return m;
}

Mat3 sym(const float* a) {
  Mat3 m;
  m << a[0], a[1], a[2], a[1], a[3], a[4], a[2], a[4], a[5];
  return m;
}

Mat3 rotation(double degrees, Eigen::Vector3d axis) {
  return Eigen::AngleAxisd(degrees * kPi / 180, axis.normalized()).toRotationMatrix();
}

//! A temporary folder per test.
struct GaussiansTest : ::testing::Test {
  std::string dir;
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir = (fs::path(::testing::TempDir()) /
           ("gen4d_gaussians_" + std::to_string(::getpid()) + "_" + info->name()))
              .string();
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  void TearDown() override { fs::remove_all(dir); }
  std::string file(const std::string& name) const { return dir + "/" + name; }
  std::size_t files_in_dir() const {
    return static_cast<std::size_t>(
        std::distance(fs::directory_iterator(dir), fs::directory_iterator()));
  }
};

// ---- hand-made PLY files (independent of the writer) ------------------------------------

struct Prop {
  std::string type, name;
};

//! The 3DGS properties in graphdeco's order for SH degree `degree` (normals optional).
std::vector<Prop> standard_props(int degree, bool normals = false) {
  std::vector<Prop> p = {{"float", "x"}, {"float", "y"}, {"float", "z"}};
  if (normals) p.insert(p.end(), {{"float", "nx"}, {"float", "ny"}, {"float", "nz"}});
  for (int c = 0; c < 3; ++c) p.push_back({"float", "f_dc_" + std::to_string(c)});
  const int rest = 3 * (sh_coefficients(degree) - 1);
  for (int j = 0; j < rest; ++j) p.push_back({"float", "f_rest_" + std::to_string(j)});
  p.push_back({"float", "opacity"});
  for (int d = 0; d < 3; ++d) p.push_back({"float", "scale_" + std::to_string(d)});
  for (int d = 0; d < 4; ++d) p.push_back({"float", "rot_" + std::to_string(d)});
  return p;
}

//! Distinct raw (file) value of property `name` of splat i.
double raw_value(const std::string& name, int i) {
  auto index = [&](const std::string& prefix) { return std::stoi(name.substr(prefix.size())); };
  if (name == "x") return 0.1 * i + 0.01;
  if (name == "y") return -0.2 * i;
  if (name == "z") return 0.5;
  if (name.rfind("f_dc_", 0) == 0) return 0.1 * index("f_dc_") - 0.05 * i;
  if (name.rfind("f_rest_", 0) == 0) return 0.01 * (index("f_rest_") + 1) + 0.001 * i;
  if (name == "opacity") return -1 + 0.5 * i;
  if (name.rfind("scale_", 0) == 0) return -3 + 0.1 * index("scale_") + 0.01 * i;
  if (name == "rot_0") return 1;
  if (name == "rot_1") return 0.1 * i;
  if (name == "rot_2") return -0.2;
  if (name == "rot_3") return 0.3;
  return 7 + i;  // any other property
}

//! A PLY with `n` vertices of the properties `props` (values from raw_value unless `value`
//! overrides), then `tail` (further header elements are added by the caller via `extra`).
std::string make_ply(const std::vector<Prop>& props, int n, bool ascii,
                     const std::function<double(const std::string&, int)>& value = raw_value,
                     const std::string& extra_header = "", const std::string& tail = "") {
  std::string s = "ply\nformat ";
  s += ascii ? "ascii 1.0\n" : "binary_little_endian 1.0\n";
  s += "comment made by test_gaussians\nelement vertex " + std::to_string(n) + "\n";
  for (const Prop& p : props) s += "property " + p.type + " " + p.name + "\n";
  s += extra_header + "end_header\n";
  for (int i = 0; i < n; ++i) {
    for (std::size_t k = 0; k < props.size(); ++k) {
      const double v = value(props[k].name, i);
      if (ascii) {
        std::ostringstream o;
        o.precision(9);
        o << static_cast<float>(v);
        s += o.str() + (k + 1 < props.size() ? " " : "\n");
      } else if (props[k].type == "double") {
        s.append(reinterpret_cast<const char*>(&v), 8);
      } else if (props[k].type == "uchar") {
        s.push_back(static_cast<char>(static_cast<unsigned char>(v)));
      } else {
        const float f = static_cast<float>(v);
        s.append(reinterpret_cast<const char*>(&f), 4);
      }
    }
  }
  return s + tail;
}

void write_bytes(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

double f32(double v) {
  return static_cast<float>(v);
}

//! Checks a set read from a make_ply file with the default values.
//! rot_tol: 0 for a file of raw values, float rounding for one the writer wrote (it holds the
//! normalised quaternion).
void expect_raw_values(const SplatSet& s, int degree, int n, double rot_tol = 1e-15) {
  ASSERT_EQ(s.size(), static_cast<std::size_t>(n));
  ASSERT_EQ(s.sh_degree, degree);
  s.check_sizes();
  const int K = sh_coefficients(degree);
  for (int i = 0; i < n; ++i) {
    EXPECT_EQ(s.position[3 * i + 0], f32(raw_value("x", i)));
    EXPECT_EQ(s.position[3 * i + 1], f32(raw_value("y", i)));
    EXPECT_EQ(s.position[3 * i + 2], f32(raw_value("z", i)));
    for (int c = 0; c < 3; ++c) {
      EXPECT_EQ(s.sh[(i * K) * 3 + c], f32(raw_value("f_dc_" + std::to_string(c), i)));
      for (int k = 1; k < K; ++k)
        EXPECT_EQ(s.sh[(i * K + k) * 3 + c],
                  f32(raw_value("f_rest_" + std::to_string((k - 1) + c * (K - 1)), i)))
            << "splat " << i << " coefficient " << k << " channel " << c;
    }
    const double logit = f32(raw_value("opacity", i));
    EXPECT_NEAR(s.opacity[i], 1 / (1 + std::exp(-logit)), 1e-15);
    for (int d = 0; d < 3; ++d)
      EXPECT_NEAR(s.scale[3 * i + d], std::exp(f32(raw_value("scale_" + std::to_string(d), i))),
                  1e-15);
    double q[4], norm = 0;
    for (int d = 0; d < 4; ++d) {
      q[d] = f32(raw_value("rot_" + std::to_string(d), i));
      norm += q[d] * q[d];
    }
    norm = std::sqrt(norm);
    for (int d = 0; d < 4; ++d) EXPECT_NEAR(s.rotation[4 * i + d], q[d] / norm, rot_tol);
  }
}

void expect_input_error(const std::function<void()>& f, const std::vector<std::string>& parts) {
  try {
    f();
    ADD_FAILURE() << "no InputError";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    for (const std::string& p : parts)
      EXPECT_NE(what.find(p), std::string::npos) << "'" << p << "' not in: " << what;
  }
}

}  // namespace

// ---- PLY ----------------------------------------------------------------------------------

TEST_F(GaussiansTest, PlyReadsTheDonut) {
  const SplatSet s = read_splats_ply(donut_path());
  ASSERT_EQ(s.size(), 45624u);
  EXPECT_EQ(s.sh_degree, 0);
  s.check_sizes();
  for (std::size_t i = 0; i < s.size(); ++i) {
    const double* q = &s.rotation[4 * i];
    EXPECT_NEAR(std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]), 1.0, 1e-6);
    EXPECT_GT(s.opacity[i], 0.0);
    EXPECT_LT(s.opacity[i], 1.0);
    for (int d = 0; d < 3; ++d) EXPECT_GT(s.scale[3 * i + d], 0.0);
  }
  // One read of the whole body: well under 0.1 s (best of three against machine noise).
  double best = 1e9;
  for (int r = 0; r < 3; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    const SplatSet again = read_splats_ply(donut_path());
    best = std::min(best,
                    std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    EXPECT_EQ(again.size(), s.size());
  }
  std::printf("donut: read in %.4f s\n", best);
  EXPECT_LT(best, 0.1);
}

TEST_F(GaussiansTest, PlyDonutRoundTrip) {
  const SplatSet first = read_splats_ply(donut_path());
  const std::string a = file("a.ply"), b = file("b.ply");
  write_splats_ply(a, first);
  const SplatSet second = read_splats_ply(a);
  ASSERT_EQ(second.size(), first.size());
  ASSERT_EQ(second.sh_degree, first.sh_degree);
  for (std::size_t i = 0; i < first.size(); ++i) {
    for (int d = 0; d < 3; ++d) {
      EXPECT_EQ(second.position[3 * i + d], first.position[3 * i + d]);
      EXPECT_NEAR(second.scale[3 * i + d], first.scale[3 * i + d], 1e-6 * first.scale[3 * i + d]);
      EXPECT_EQ(second.sh[3 * i + d], first.sh[3 * i + d]);
    }
    EXPECT_NEAR(second.opacity[i], first.opacity[i], 1e-7);
    for (int d = 0; d < 4; ++d)
      EXPECT_NEAR(second.rotation[4 * i + d], first.rotation[4 * i + d], 1e-7);
  }
  write_splats_ply(b, second);
  const std::string bytes_a = slurp(a), bytes_b = slurp(b);
  EXPECT_EQ(bytes_a.size(), 45624u * 17 * 4 + bytes_a.find("end_header\n") + 11);
  EXPECT_TRUE(bytes_a == bytes_b) << "the writer's output re-read and re-written differs";
  EXPECT_EQ(files_in_dir(), 2u);  // no temporaries left
}

TEST_F(GaussiansTest, PlyDegreesOneToThree) {
  for (int degree = 1; degree <= 3; ++degree) {
    SCOPED_TRACE("degree " + std::to_string(degree));
    const int n = 3, K = sh_coefficients(degree);
    const std::string in = file("in" + std::to_string(degree) + ".ply");
    write_bytes(in, make_ply(standard_props(degree, true), n, false));
    const SplatSet s = read_splats_ply(in);
    expect_raw_values(s, degree, n);
    // Specific coefficients: f_rest is channel-major in the file.
    EXPECT_EQ(s.sh[(1 * K + 1) * 3 + 1], f32(raw_value("f_rest_" + std::to_string(K - 1), 1)));
    EXPECT_EQ(s.sh[(2 * K + K - 1) * 3 + 2],
              f32(raw_value("f_rest_" + std::to_string(3 * (K - 1) - 1), 2)));

    // The writer's output: graphdeco's header and the file's coefficient at each f_rest_j.
    const std::string out = file("out" + std::to_string(degree) + ".ply");
    write_splats_ply(out, s);
    const std::string bytes = slurp(out);
    const std::size_t body = bytes.find("end_header\n") + 11;
    std::string header = "ply\nformat binary_little_endian 1.0\nelement vertex 3\n";
    for (const Prop& p : standard_props(degree, true)) header += "property float " + p.name + "\n";
    header += "end_header\n";
    EXPECT_EQ(bytes.substr(0, body), header);
    const std::size_t per = standard_props(degree, true).size();
    ASSERT_EQ(bytes.size(), body + 4 * per * n);
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < 3 * (K - 1); ++j) {
        float v;
        std::memcpy(&v, &bytes[body + 4 * (per * i + 9 + j)], 4);
        EXPECT_EQ(v, static_cast<float>(raw_value("f_rest_" + std::to_string(j), i)));
      }
    // Normals are written as zeros.
    float nx;
    std::memcpy(&nx, &bytes[body + 4 * 3], 4);
    EXPECT_EQ(nx, 0.0f);
    expect_raw_values(read_splats_ply(out), degree, n, 6e-8);
  }
}

TEST_F(GaussiansTest, PlyAsciiShuffledAndExtraProperties) {
  const int degree = 2, n = 4;
  const std::string binary = file("binary.ply");
  write_bytes(binary, make_ply(standard_props(degree), n, false));
  const SplatSet reference = read_splats_ply(binary);
  expect_raw_values(reference, degree, n);

  const std::string ascii = file("ascii.ply");
  write_bytes(ascii, make_ply(standard_props(degree), n, true));
  expect_raw_values(read_splats_ply(ascii), degree, n);

  // Shuffled order, unused properties of other types, a later element (ignored).
  std::vector<Prop> props = standard_props(degree, true);
  std::reverse(props.begin(), props.end());
  std::swap(props[2], props[7]);
  props.insert(props.begin() + 5, {"uchar", "red"});
  props.push_back({"double", "extra"});
  const std::string later = "element face 1\nproperty list uchar int vertex_indices\n";
  const std::string shuffled = file("shuffled.ply");
  write_bytes(shuffled, make_ply(props, n, false, raw_value, later, std::string(13, '\1')));
  expect_raw_values(read_splats_ply(shuffled), degree, n);
  const std::string shuffled_ascii = file("shuffled_ascii.ply");
  write_bytes(shuffled_ascii, make_ply(props, n, true, raw_value, later, "3 0 1 2\n"));
  expect_raw_values(read_splats_ply(shuffled_ascii), degree, n);
}

TEST_F(GaussiansTest, PlyBadFiles) {
  const std::vector<Prop> good = standard_props(1);
  auto bad = [&](const std::string& name, const std::string& bytes,
                 std::vector<std::string> parts) {
    SCOPED_TRACE(name);
    const std::string path = file(name + ".ply");
    write_bytes(path, bytes);
    parts.push_back(path);
    expect_input_error([&] { read_splats_ply(path); }, parts);
  };
  {
    std::vector<Prop> p = good;
    p.erase(p.end() - 2);  // rot_2
    bad("missing", make_ply(p, 2, false), {"'rot_2'", "missing"});
  }
  {
    std::vector<Prop> p = good;
    for (Prop& q : p)
      if (q.name == "opacity") q.type = "double";
    bad("double", make_ply(p, 2, false), {"'opacity'", "double"});
  }
  {
    std::vector<Prop> p = standard_props(0);
    for (int j = 0; j < 7; ++j)
      p.insert(p.begin() + 6, {"float", "f_rest_" + std::to_string(6 - j)});
    bad("rest7", make_ply(p, 2, false), {"7 f_rest"});
  }
  {
    std::string bytes = make_ply(good, 5, false);
    bytes.resize(bytes.size() - 4 * good.size() - 3);  // row 3 cut short, row 4 absent
    bad("truncated", bytes, {"row 3 ", "truncated"});
    std::string text = make_ply(good, 5, true);
    text.resize(text.rfind('\n', text.size() - 2) + 1);  // row 4 absent
    bad("truncated_ascii", text, {"row 4 ", "truncated"});
    // One-character values: the rows the body can hold are counted before it is parsed, and
    // row 1, cut after three values, lies past that count (a heap overflow found by fuzz_ply).
    std::string zeros = make_ply(good, 2, true, [](const std::string&, int) { return 0.0; });
    zeros.resize(zeros.size() - 2 * good.size() + 6);
    bad("truncated_ascii_short_values", zeros, {"row 1 ", "truncated", "'" + good[3].name + "'"});
  }
  auto with = [](const std::string& prop, int row, double v) {
    return [=](const std::string& name, int i) {
      return name == prop && i == row ? v : raw_value(name, i);
    };
  };
  bad("nan", make_ply(good, 4, false, with("f_rest_5", 2, std::nan(""))),
      {"row 2,", "'f_rest_5'", "nan"});
  bad("inf", make_ply(good, 4, false, with("y", 3, HUGE_VAL)), {"row 3,", "'y'", "inf"});
  bad("inf_ascii", make_ply(good, 4, true, with("scale_1", 1, -HUGE_VAL)),
      {"row 1,", "'scale_1'", "inf"});
  bad("zero_quaternion",
      make_ply(good, 4, false,
               [](const std::string& name, int i) {
                 return i == 1 && name.rfind("rot_", 0) == 0 ? 0.0 : raw_value(name, i);
               }),
      {"row 1 ", "zero quaternion"});
  bad("not_ply", "solid cube\nfacet normal 0 0 1\n", {"not a PLY"});
  bad("empty", "", {"not a PLY"});
  bad("big_endian", "ply\nformat binary_big_endian 1.0\nelement vertex 0\nend_header\n",
      {"line 2", "binary_big_endian"});
  bad("no_end", "ply\nformat ascii 1.0\nelement vertex 0\n", {"end_header"});
  {
    std::string text = make_ply(good, 2, true, with("z", 1, 0.125));
    text.replace(text.find("0.125"), 5, "0,125");
    bad("comma", text, {"row 1,", "'z'", "0,125"});
  }
  const std::string missing = file("no_such.ply");
  expect_input_error([&] { read_splats_ply(missing); }, {missing, "cannot open"});
}

TEST_F(GaussiansTest, PlyWriterFailuresLeaveNothing) {
  SplatSet s = read_splats_ply([&] {
    const std::string p = file("src.ply");
    write_bytes(p, make_ply(standard_props(1), 3, false));
    return p;
  }());
  // A folder that does not exist: nothing written.
  const std::string nowhere = file("no_dir/out.ply");
  EXPECT_THROW(write_splats_ply(nowhere, s), RuntimeError);
  EXPECT_FALSE(fs::exists(file("no_dir")));
  // A name that is a folder: the rename fails, the temporary is removed.
  fs::create_directories(file("folder.ply"));
  EXPECT_THROW(write_splats_ply(file("folder.ply"), s), RuntimeError);
  EXPECT_TRUE(fs::is_directory(file("folder.ply")));
  EXPECT_EQ(files_in_dir(), 2u);
  // Values a file cannot hold: the old file is kept untouched.
  const std::string out = file("out.ply");
  write_splats_ply(out, s);
  const std::string before = slurp(out);
  SplatSet saturated = s;
  saturated.opacity[1] = 1.0;
  EXPECT_THROW(write_splats_ply(out, saturated), RuntimeError);
  SplatSet huge = s;
  huge.position[4] = 1e300;
  EXPECT_THROW(write_splats_ply(out, huge), RuntimeError);
  SplatSet inconsistent = s;
  inconsistent.sh.pop_back();
  EXPECT_THROW(write_splats_ply(out, inconsistent), std::logic_error);
  EXPECT_EQ(slurp(out), before);
  EXPECT_EQ(files_in_dir(), 3u);
}

// ---- covariance and kinematics ------------------------------------------------------------

TEST(GaussiansKinematics, CovarianceOfKnownQuaternionAndScale) {
  SplatSet s;
  const double h = std::sqrt(0.5);
  // 90 degrees about z (x -> y), 90 degrees about x (y -> z), 45 degrees about z, unnormalised.
  s.rotation = {h, 0, 0, h, h, h, 0, 0, 2 * std::cos(kPi / 8), 0, 0, 2 * std::sin(kPi / 8)};
  s.scale = {1, 2, 3, 1, 2, 3, 1, 2, 3};
  s.position.assign(9, 0.0);
  s.opacity.assign(3, 0.5);
  s.sh.assign(9, 0.0);
  s.check_sizes();
  const std::array<std::array<double, 6>, 3> expected = {
      {{4, 0, 0, 1, 0, 9}, {1, 0, 0, 9, 0, 4}, {2.5, -1.5, 0, 2.5, 0, 9}}};
  for (int i = 0; i < 3; ++i) {
    const std::array<double, 6> c = s.covariance(i);
    for (int k = 0; k < 6; ++k) EXPECT_NEAR(c[k], expected[i][k], 1e-12) << i << " " << k;
  }
  s.sh.pop_back();
  EXPECT_THROW(s.check_sizes(), std::logic_error);
}

TEST(GaussiansKinematics, PolarRotation) {
  const Mat3 R = rotation(37, {1, 2, -0.5});
  Mat3 S;
  S << 2.0, 0.3, -0.1, 0.3, 1.5, 0.2, -0.1, 0.2, 0.7;  // symmetric positive definite
  const Mat3 got = to_mat(polar_rotation(to_array(R * S)));
  EXPECT_LT((got - R).norm(), 1e-12);

  // Inverted: det F < 0 still gives a rotation, with F = R' S' and S' symmetric whose one
  // negative eigenvalue is the smallest in magnitude.
  const Mat3 F = R * Eigen::Vector3d(1, 2, -3).asDiagonal();
  const Mat3 Ri = to_mat(polar_rotation(to_array(F)));
  EXPECT_NEAR(Ri.determinant(), 1.0, 1e-12);
  EXPECT_LT((Ri * Ri.transpose() - Mat3::Identity()).norm(), 1e-12);
  const Mat3 Si = Ri.transpose() * F;
  EXPECT_LT((Si - Si.transpose()).norm(), 1e-12);
  Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Mat3>(Si).eigenvalues();
  EXPECT_NEAR(ev[0], -1, 1e-12);
  EXPECT_NEAR(ev[1], 2, 1e-12);
  EXPECT_NEAR(ev[2], 3, 1e-12);

  // Degenerate F: zero, rank one, rank two, a reflection.
  Mat3 rank1 = Eigen::Vector3d(1, 2, 3) * Eigen::RowVector3d(0.5, -1, 0.25);
  Mat3 rank2 = R * Eigen::Vector3d(1, 0, 2).asDiagonal();
  Mat3 reflect = Mat3::Identity();
  reflect(2, 2) = -1;
  for (const Mat3& d : {Mat3(Mat3::Zero()), rank1, rank2, reflect}) {
    const Mat3 r = to_mat(polar_rotation(to_array(d)));
    EXPECT_NEAR(r.determinant(), 1.0, 1e-12);
    EXPECT_LT((r * r.transpose() - Mat3::Identity()).norm(), 1e-12);
  }
  std::array<double, 9> bad = to_array(R);
  bad[4] = std::nan("");
  EXPECT_THROW(polar_rotation(bad), RuntimeError);
}

TEST(GaussiansKinematics, DeformedFixedRigidCovariances) {
  SplatSet rest;
  rest.sh_degree = 1;
  rest.position = {0, 0, 0};
  rest.scale = {0.1, 0.2, 0.3};
  rest.rotation = {1, 0, 0, 0};
  rest.opacity = {0.7};
  for (int k = 0; k < 12; ++k) rest.sh.push_back(0.1 * k);
  const Mat3 Rz = rotation(90, {0, 0, 1});
  const Mat3 F = Rz * Eigen::Vector3d(2, 1, 1).asDiagonal();
  const std::array<double, 9> f = to_array(F);
  const double x[3] = {1, 2, 3};
  auto run = [&](const std::string& name, const double* override_cov = nullptr) {
    SplatFrame frame;
    frame.sh_degree = 1;
    append_deformed(rest, 0, x, f.data(), KinematicsOptions::parse(name, "test"), frame,
                    override_cov);
    EXPECT_EQ(frame.size(), 1u);
    EXPECT_EQ(frame.position, (std::vector<float>{1, 2, 3}));
    EXPECT_EQ(frame.opacity[0], 0.7f);
    EXPECT_EQ(frame.sh.size(), 12u);
    EXPECT_EQ(frame.sh[5], 0.5f);
    return frame;
  };
  auto expect_cov = [](const SplatFrame& frame, const Eigen::Vector3d& diagonal) {
    const Mat3 expected = Mat3(diagonal.asDiagonal());
    EXPECT_LT((sym(frame.covariance.data()) - expected).norm(), 1e-8)
        << sym(frame.covariance.data());
  };
  const SplatFrame full = run("full");
  expect_cov(full, {0.04, 0.04, 0.09});  // F A0 F^T
  ASSERT_EQ(full.sh_rotation.size(), 9u);
  for (int k = 0; k < 9; ++k) EXPECT_NEAR(full.sh_rotation[k], Rz(k / 3, k % 3), 1e-7);
  expect_cov(run("fixed_covariance"), {0.01, 0.04, 0.09});  // A0
  expect_cov(run("rigid_covariance"), {0.04, 0.01, 0.09});  // R A0 R^T
  const SplatFrame fixed_sh = run("fixed_harmonics");
  expect_cov(fixed_sh, {0.04, 0.04, 0.09});
  EXPECT_TRUE(fixed_sh.sh_rotation.empty());
  const double rate[6] = {0.5, 0, 0, 0.25, 0, 0.125};
  expect_cov(run("full", rate), {0.5, 0.25, 0.125});
  expect_cov(run("fixed_covariance", rate), {0.01, 0.04, 0.09});

  // Frames append; mismatched degrees are refused.
  SplatFrame all;
  all.append(full);
  all.append(full);
  EXPECT_EQ(all.size(), 2u);
  EXPECT_EQ(all.sh_rotation.size(), 18u);
  EXPECT_EQ(all.sh_degree, 1);
  SplatFrame degree0;
  degree0.position = {0, 0, 0};
  degree0.covariance.assign(6, 0.f);
  degree0.opacity = {0.5f};
  degree0.sh = {0, 0, 0};
  EXPECT_THROW(all.append(degree0), std::logic_error);
  EXPECT_THROW(all.append(fixed_sh), std::logic_error);  // no sh_rotation
  SplatFrame wrong;
  EXPECT_THROW(append_deformed(rest, 0, x, f.data(), KinematicsOptions{}, wrong), std::logic_error);

  // rest_frame: F = I.
  const SplatFrame r = rest_frame(rest);
  expect_cov(r, {0.01, 0.04, 0.09});
  EXPECT_TRUE(r.sh_rotation.empty());
  EXPECT_EQ(r.sh_degree, 1);

  expect_input_error([] { KinematicsOptions::parse("wobbly", "deck.toml:12 render.kinematics"); },
                     {"deck.toml:12 render.kinematics", "wobbly"});
}

TEST(GaussiansKinematics, RateUpdateMatchesDeformedToFirstOrder) {
  Mat3 L;
  L << 0.3, -1.2, 0.4, 0.8, -0.5, 0.1, -0.2, 0.6, 0.9;
  const std::array<double, 6> A = {0.04, 0.01, -0.005, 0.09, 0.02, 0.01};
  auto error = [&](double dt) {
    std::array<double, 6> a = A;
    rate_update_covariance(to_array(L), dt, a);
    const Mat3 F = Mat3::Identity() + dt * L;
    const Mat3 exact = sym(transform_covariance(to_array(F), A));
    EXPECT_LT((sym(a) - sym(a).transpose()).norm(), 1e-15);
    return (sym(a) - exact).norm();
  };
  // The difference is dt^2 L A L^T: second order.
  const double e1 = error(1e-3), e2 = error(5e-4);
  const double second = (L * sym(A) * L.transpose()).norm();
  EXPECT_NEAR(e1, 1e-6 * second, 1e-3 * 1e-6 * second);
  EXPECT_NEAR(e1 / e2, 4.0, 1e-3);
  // And the change itself is first order (not zero).
  std::array<double, 6> a = A;
  rate_update_covariance(to_array(L), 1e-3, a);
  EXPECT_GT((sym(a) - sym(A)).norm(), 100 * e1);
}

// ---- deck splat objects -------------------------------------------------------------------

TEST_F(GaussiansTest, LoadGeometrySplatsTransforms) {
  // Splat 0 at (1, 0, 0) with scale (0.1, 0.2, 0.3), splat 1 nearly transparent, splat 2 at
  // the origin.
  const std::string path = file("three.ply");
  write_bytes(path, make_ply(standard_props(0), 3, false, [](const std::string& name, int i) {
                const double pos[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 0}};
                if (name == "x" || name == "y" || name == "z") return pos[i][name[0] - 'x'];
                if (name == "opacity") return i == 1 ? -5.0 : 2.0;  // 0.0067 : 0.88
                if (name.rfind("scale_", 0) == 0) return std::log(0.1 * (name[6] - '0' + 1));
                if (name == "rot_0") return 1.0;
                if (name.rfind("rot_", 0) == 0) return 0.0;
                return 0.25;
              }));
  gen4d::GeometryConfig g;
  g.type = "splats";
  g.file = path;
  g.rotate_axis = {0, 0, 2};
  g.rotate_degrees = 90;
  g.scale = 2;
  g.translate = {1, 0, 0};
  const SplatSet s = load_geometry_splats(g);
  ASSERT_EQ(s.size(), 2u);  // opacity threshold 0.02 drops splat 1
  EXPECT_NEAR(s.position[0], 1, 1e-12);
  EXPECT_NEAR(s.position[1], 2, 1e-12);
  EXPECT_NEAR(s.position[2], 0, 1e-12);
  EXPECT_NEAR(s.position[3], 1, 1e-12);
  const Mat3 cov = sym(s.covariance(0));
  const Mat3 expected = Mat3(Eigen::Vector3d(4 * 0.04, 4 * 0.01, 4 * 0.09).asDiagonal());
  EXPECT_LT((cov - expected).norm(), 1e-6);
  EXPECT_NEAR(s.scale[2], 0.6, 1e-6);

  g.opacity_threshold = 0.9;
  expect_input_error([&] { load_geometry_splats(g); }, {path, "opacity"});
  g.opacity_threshold = 0.02;
  g.rotate_axis = {0, 0, 0};
  expect_input_error([&] { load_geometry_splats(g); }, {path, "rotate_axis"});
  g.file = file("absent.ply");
  g.rotate_degrees = 0;
  expect_input_error([&] { load_geometry_splats(g); }, {g.file});
}

TEST(GaussiansDeck, TransformRotatesHarmonicsWithTheObject) {
  // Degree 3 coefficients; after the transform, the colour seen along d equals the colour
  // seen along R^T d before, evaluated by the renderer's SH code.
  SplatSet s;
  s.sh_degree = 3;
  s.position = {0.1, 0.2, 0.3};
  s.scale = {0.01, 0.02, 0.03};
  s.rotation = {1, 0, 0, 0};
  s.opacity = {0.5};
  for (int k = 0; k < 48; ++k) s.sh.push_back(0.05 * std::sin(1.7 * k + 0.3));
  const SplatSet before = s;
  const Mat3 R = rotation(70, {0.3, -1, 0.6});
  transform_splats(s, 1.5, to_array(R), {0, 0, 0});
  const std::vector<float> old_sh(before.sh.begin(), before.sh.end());
  const std::vector<float> new_sh(s.sh.begin(), s.sh.end());
  EXPECT_EQ(new_sh[0], old_sh[0]);
  double worst = 0, spread = 0;
  for (int j = 0; j < 50; ++j) {
    const Eigen::Vector3d d =
        Eigen::Vector3d(std::sin(j), std::cos(2.3 * j), std::sin(0.7 * j + 1)).normalized();
    const Eigen::Vector3d back = R.transpose() * d;
    float now[3], then[3], same_d[3];
    sh_color(3, new_sh.data(), d.x(), d.y(), d.z(), now);
    sh_color(3, old_sh.data(), back.x(), back.y(), back.z(), then);
    sh_color(3, old_sh.data(), d.x(), d.y(), d.z(), same_d);
    for (int c = 0; c < 3; ++c) {
      worst = std::max(worst, std::abs(double(now[c]) - then[c]));
      spread = std::max(spread, std::abs(double(same_d[c]) - then[c]));
    }
  }
  EXPECT_LT(worst, 1e-6);
  EXPECT_GT(spread, 1e-2);  // the rotation matters for these coefficients
  const Mat3 cov = sym(s.covariance(0));
  const Mat3 expected = 2.25 * R * sym(before.covariance(0)) * R.transpose();
  EXPECT_LT((cov - expected).norm(), 1e-15);
  EXPECT_THROW(transform_splats(s, 1, to_array(2 * R), {0, 0, 0}), std::invalid_argument);
  EXPECT_THROW(transform_splats(s, 0, to_array(R), {0, 0, 0}), std::invalid_argument);
}

TEST(GaussiansDeck, SplatsFromShape) {
  const gen4d::geometry::Box box({0, 0, 0}, {1, 0.5, 0.2});
  const std::array<double, 3> color = {0.9, 0.5, 0.1};
  const SplatSet s = splats_from_shape(box, 0.1, color);
  ASSERT_EQ(s.size(), 100u);  // 10 x 5 x 2 cell centres
  s.check_sizes();
  EXPECT_EQ(s.sh_degree, 0);
  EXPECT_NEAR(s.position[0], 0.05, 1e-12);
  EXPECT_NEAR(s.position[3], 0.15, 1e-12);  // x fastest
  EXPECT_NEAR(s.position[3 * 10 + 1], 0.15, 1e-12);
  EXPECT_NEAR(s.position[3 * 99 + 2], 0.15, 1e-12);
  for (std::size_t i = 0; i < s.size(); ++i) {
    EXPECT_EQ(s.scale[3 * i], 0.05);
    EXPECT_EQ(s.opacity[i], 0.95);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(kC0 * s.sh[3 * i + c] + 0.5, color[c], 1e-15);
  }
  // A ball: the count follows its volume.
  const gen4d::geometry::Sphere ball({0, 0, 0}, 1.0);
  const SplatSet b = splats_from_shape(ball, 0.05, color, 0.5);
  EXPECT_NEAR(static_cast<double>(b.size()), 4.0 / 3 * kPi / (0.05 * 0.05 * 0.05), 0.01 * 33510);
  EXPECT_THROW(splats_from_shape(box, 0, color), std::invalid_argument);
}

namespace {

//! Splat centres on a sphere (Fibonacci points), isotropic and opaque.
SplatSet sphere_shell(const Eigen::Vector3d& c, double r, int n) {
  SplatSet s;
  for (int j = 0; j < n; ++j) {
    const double z = 1 - (2 * j + 1.0) / n;
    const double rho = std::sqrt(1 - z * z);
    const double phi = j * kPi * (3 - std::sqrt(5.0));
    const Eigen::Vector3d p = c + r * Eigen::Vector3d(rho * std::cos(phi), rho * std::sin(phi), z);
    s.position.insert(s.position.end(), {p.x(), p.y(), p.z()});
    s.scale.insert(s.scale.end(), {0.001, 0.001, 0.001});
    s.rotation.insert(s.rotation.end(), {1, 0, 0, 0});
    s.opacity.push_back(0.9);
    s.sh.insert(s.sh.end(), {0, 0, 0});
  }
  return s;
}

}  // namespace

TEST(GaussiansDeck, OccupancyFillsASphereShell) {
  const double h = 0.01, r = 0.3;
  const Eigen::Vector3d c(0.5, 0.5, 0.5);
  const SplatSet shell = sphere_shell(c, r, 200000);
  const SplatOccupancy occ(shell, h, {0, 0, 0});
  const double ball = 4.0 / 3 * kPi * std::pow(r / h, 3);
  const long solid = occ.solid_cells();
  std::printf("shell: %zu occupied cells, %ld solid, ball %.0f cells (%.2f %%)\n",
              occ.occupied_cells(), solid, ball, 100.0 * (solid - ball) / ball);
  EXPECT_NEAR(static_cast<double>(solid), ball, 0.15 * ball);
  EXPECT_LT(static_cast<double>(occ.occupied_cells()), 0.3 * ball);  // the shell alone
  EXPECT_TRUE(occ.inside(c));
  EXPECT_FALSE(occ.inside(c + Eigen::Vector3d(0, 0, r + 2 * h)));
  EXPECT_FALSE(occ.inside(c + Eigen::Vector3d(0.8 * r, 0.8 * r, 0)));
  for (int d = 0; d < 3; ++d) {
    EXPECT_NEAR(occ.bounds().lo[d], c[d] - r, 1.01 * h);
    EXPECT_NEAR(occ.bounds().hi[d], c[d] + r, 1.01 * h);
  }
  // Voxelizing through the Shape interface sees the same solid.
  std::vector<std::uint8_t> voxels;
  gen4d::geometry::voxelize(occ, {0, 0, 0}, h, {0, 0, 0}, {100, 100, 100}, voxels);
  EXPECT_EQ(gen4d::geometry::count_solid(voxels), solid);
  // Every cell well inside the ball is solid.
  long interior = 0, missed = 0;
  for (long k = 0; k < 100; ++k)
    for (long j = 0; j < 100; ++j)
      for (long i = 0; i < 100; ++i)
        if ((h * Eigen::Vector3d(i + 0.5, j + 0.5, k + 0.5) - c).norm() < r - 2 * h) {
          ++interior;
          missed += voxels[(k * 100 + j) * 100 + i] == 0;
        }
  EXPECT_GT(interior, 0);
  EXPECT_EQ(missed, 0);

  // min_count: cells holding fewer splats are not occupied.
  SplatSet two = sphere_shell(c, 0.0, 1);  // one splat at the centre
  two.position.insert(two.position.end(), {0.105, 0.105, 0.105, 0.106, 0.106, 0.106});
  for (int k = 0; k < 2; ++k) {
    two.scale.insert(two.scale.end(), {0.001, 0.001, 0.001});
    two.rotation.insert(two.rotation.end(), {1, 0, 0, 0});
    two.opacity.push_back(0.9);
    two.sh.insert(two.sh.end(), {0, 0, 0});
  }
  const SplatOccupancy pairs(two, h, {0, 0, 0}, 2);
  EXPECT_EQ(pairs.occupied_cells(), 1u);
  EXPECT_TRUE(pairs.inside({0.1055, 0.1055, 0.1055}));
  EXPECT_FALSE(pairs.inside(c));
  EXPECT_EQ(SplatOccupancy(two, h, {0, 0, 0}).occupied_cells(), 2u);
  EXPECT_TRUE(SplatOccupancy(SplatSet{}, h, {0, 0, 0}).bounds().empty());
}

TEST(GaussiansDeck, DonutOccupancy) {
  const SplatSet donut = read_splats_ply(donut_path());
  gen4d::geometry::Aabb box;
  for (std::size_t i = 0; i < donut.size(); ++i)
    box.extend(Eigen::Vector3d(donut.position[3 * i], donut.position[3 * i + 1],
                               donut.position[3 * i + 2]));
  const double h = 0.01;
  const auto t0 = std::chrono::steady_clock::now();
  const SplatOccupancy occ(donut, h, {box.lo.x(), box.lo.y(), box.lo.z()});
  const double built = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const long solid = occ.solid_cells();
  const Eigen::Vector3d extent = box.hi - box.lo;
  const double box_volume = extent.prod();
  const double solid_volume = solid * h * h * h;
  std::printf(
      "donut: box %.3f x %.3f x %.3f, %zu occupied cells, %ld solid cells "
      "(%.5f m^3, %.1f %% of the box), built in %.4f s\n",
      extent.x(), extent.y(), extent.z(), occ.occupied_cells(), solid, solid_volume,
      100 * solid_volume / box_volume, built);
  EXPECT_GT(solid, static_cast<long>(occ.occupied_cells()));
  EXPECT_LT(solid_volume, box_volume);
  // A ring about z (the thin axis): its hole stays open, its tube is solid.
  const Eigen::Vector3d centre = 0.5 * (box.lo + box.hi);
  const double tube = 0.25 * (extent.x() + extent.y()) - 0.5 * extent.z();  // ring radius
  EXPECT_FALSE(occ.inside(centre));
  for (int a = 0; a < 8; ++a) {
    const double t = a * kPi / 4;
    EXPECT_TRUE(occ.inside(centre + tube * Eigen::Vector3d(std::cos(t), std::sin(t), 0))) << a;
  }
  const SplatOccupancy fine(donut, h / 2, {box.lo.x(), box.lo.y(), box.lo.z()});
  std::printf("donut at h = %.3f: %zu occupied cells, %ld solid cells (%.5f m^3)\n", h / 2,
              fine.occupied_cells(), fine.solid_cells(), fine.solid_cells() * std::pow(h / 2, 3));
  EXPECT_FALSE(fine.inside(centre));
}
