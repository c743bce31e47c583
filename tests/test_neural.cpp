// NeuralMTL's fused kernel against a plain reference, its activation (zero at rest,
// symmetric, rotation invariant), the exact gradient, and its weight files (round trip and
// every kind of bad file).
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/Error.hpp"
#include "core/ParallelFor.hpp"
#include "neural/ArrayFile.hpp"
#include "neural/NeuralMtl.hpp"
#include "neural_test_util.hpp"
#include "mat3_test_util.hpp"

namespace gn = gen4d::neural;
using gen4d::materials::Mat3;
using gen4d::test::from_eigen;
using gen4d::test::to_eigen;

namespace {

gn::NeuralMtlWeights random_weights(unsigned seed, const std::vector<int>& hidden = {24, 24}) {
  return gen4d::test::random_weights(seed, hidden);
}

// Textbook evaluation with std::tanh and no folding, for the kernel to match.
void reference(const gn::NeuralMtlWeights& w, const double sigma[3], double n[3]) {
  auto raw = [&](const double x[3], double out[3]) {
    std::vector<double> h(x, x + 3);
    for (std::size_t l = 0; l < w.layers.size(); ++l) {
      const auto& L = w.layers[l];
      std::vector<double> next(L.out);
      for (int j = 0; j < L.out; ++j) {
        double a = L.b[j];
        for (int i = 0; i < L.in; ++i) a += L.W[j * L.in + i] * h[i];
        next[j] = l + 1 < w.layers.size() ? std::tanh(a) : a;
      }
      h = next;
    }
    for (int a = 0; a < 3; ++a) out[a] = h[a];
  };
  const double x[3] = {sigma[0] - 1, sigma[1] - 1, sigma[2] - 1}, zero[3] = {0, 0, 0};
  double m[3], m0[3];
  raw(x, m);
  raw(zero, m0);
  for (int a = 0; a < 3; ++a) n[a] = m[a] - m0[a];
}

std::string scratch(const std::string& name) {
  const auto d = std::filesystem::path(GEN4D_BINARY_DIR) / "tests" / "scratch" / "neural";
  std::filesystem::create_directories(d);
  return (d / name).string();
}

template <class F>
std::string input_error(F&& f) {
  try {
    f();
  } catch (const gen4d::InputError& e) {
    return e.what();
  }
  return "(no InputError)";
}

}  // namespace

// Every instruction-set build of the kernel this CPU runs, on several architectures (widths
// padded inside the kernel, a 64-wide layer, three hidden layers).
TEST(NeuralMtl, KernelMatchesReferenceIncludingPartialLanes) {
  const std::string in_use = gn::NeuralMtl::isa();
  for (const std::string& isa : gn::NeuralMtl::isas()) {
    gn::NeuralMtl::select_isa(isa);
    for (const std::vector<int>& hidden :
         std::vector<std::vector<int>>{{24, 24}, {64, 5}, {16, 20, 12}}) {
      const auto w = random_weights(1, hidden);
      const gn::NeuralMtl net(w);
      for (std::size_t n : {1u, 3u, 7u, 8u, 13u, 1000u}) {
        const auto s = gen4d::test::random_sigmas(n, 10 + n);
        std::vector<double> strain(3 * n), psi(n), grad(3 * n);
        net.strain(n, s.data(), strain.data());
        net.evaluate(n, s.data(), psi.data(), grad.data());
        for (std::size_t p = 0; p < n; ++p) {
          double ref[3];
          reference(w, &s[3 * p], ref);
          for (int a = 0; a < 3; ++a)
            EXPECT_NEAR(strain[3 * p + a], ref[a], 1e-13)
                << isa << " " << hidden.size() << " " << p;
          EXPECT_NEAR(psi[p], 0.5 * (ref[0] * ref[0] + ref[1] * ref[1] + ref[2] * ref[2]), 1e-13)
              << isa;
        }
      }
    }
  }
  gn::NeuralMtl::select_isa(in_use);
  EXPECT_THROW(gn::NeuralMtl::select_isa("sse9"), std::invalid_argument);
}

// The batch is shared among host threads; each point's result must not depend on how.
TEST(NeuralMtl, ThreadsGiveIdenticalResults) {
  const gn::NeuralMtl net(random_weights(9));
  const std::size_t n = 40001;  // above the serial threshold, a partial lane group at the end
  const auto s = gen4d::test::random_sigmas(n, 4);
  auto run = [&](int threads) {
    const int before = gen4d::exec::host_threads();
#if defined(_OPENMP)
    omp_set_num_threads(threads);
#endif
    std::vector<double> out(4 * n);
    net.evaluate(n, s.data(), out.data(), out.data() + n);
#if defined(_OPENMP)
    omp_set_num_threads(before);
#endif
    return out;
  };
  const auto one = run(1), two = run(2), three = run(3);
  EXPECT_EQ(one, two);
  EXPECT_EQ(one, three);
}

TEST(NeuralMtl, GradientIsTheDerivativeOfTheEnergy) {
  const gn::NeuralMtl net(random_weights(2));
  const auto s = gen4d::test::random_sigmas(50, 3);
  std::vector<double> psi(50), grad(150);
  net.evaluate(50, s.data(), psi.data(), grad.data());
  const double h = 1e-6;
  for (std::size_t p = 0; p < 50; ++p)
    for (int a = 0; a < 3; ++a) {
      double sp[3] = {s[3 * p], s[3 * p + 1], s[3 * p + 2]}, sm[3] = {sp[0], sp[1], sp[2]};
      sp[a] += h;
      sm[a] -= h;
      double ep, em;
      net.evaluate(1, sp, &ep, nullptr);
      net.evaluate(1, sm, &em, nullptr);
      EXPECT_NEAR(grad[3 * p + a], (ep - em) / (2 * h), 1e-7 * (1 + std::fabs(grad[3 * p + a])));
    }
}

TEST(NeuralMtl, ActivationVanishesAtRest) {
  const gn::NeuralMtl net(random_weights(3));
  const double rest[3] = {1, 1, 1};
  double n[3], psi, grad[3];
  net.strain(1, rest, n);
  net.evaluate(1, rest, &psi, grad);
  for (int a = 0; a < 3; ++a) {
    EXPECT_EQ(n[a], 0.0);
    EXPECT_EQ(grad[a], 0.0);
  }
  EXPECT_EQ(psi, 0.0);
}

TEST(NeuralMtl, NeuralStrainIsSymmetricAndRotationInvariant) {
  const gn::NeuralMtl net(random_weights(4));
  const gn::NeuralMaterial mat{&net, 2e5, 1e6};
  std::mt19937_64 rng(5);
  std::normal_distribution<double> normal;
  for (int trial = 0; trial < 50; ++trial) {
    Eigen::Matrix3d F = Eigen::Matrix3d::Identity();
    for (int i = 0; i < 9; ++i) F.data()[i] += 0.25 * normal(rng);
    if (F.determinant() < 0.2) continue;
    const Eigen::Matrix3d Q = Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng))
                                  .normalized()
                                  .toRotationMatrix();
    Mat3 P, PQ;
    const double e = mat.energy_and_pk1(from_eigen(F), P);
    const double eq = mat.energy_and_pk1(from_eigen(Q * F), PQ);
    EXPECT_NEAR(eq, e, 1e-10 * std::fabs(e));
    // Rotating the deformation rotates the stress: P(QF) = Q P(F).
    EXPECT_LT((to_eigen(PQ) - Q * to_eigen(P)).norm(), 1e-9 * (1 + to_eigen(P).norm()));
    // Neural projection: target p = F - P/k = R S with R = U V^T and S symmetric.
    const Eigen::Matrix3d p = F - to_eigen(P) / mat.stiffness;
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
    const Eigen::Matrix3d R = svd.matrixU() * svd.matrixV().transpose();
    const Eigen::Matrix3d S = R.transpose() * p;
    EXPECT_LT((S - S.transpose()).norm(), 1e-9 * S.norm());
  }
}

TEST(NeuralMtl, LawEnergyGradientAndRest) {
  for (int law = 0; law < 3; ++law) {
    const double rest[3] = {1, 1, 1};
    double g[3];
    EXPECT_NEAR(gn::law_energy(law, 0.3, rest, g), 0.0, 1e-14);
    const auto s = gen4d::test::random_sigmas(20, 7 + law);
    for (int p = 0; p < 20; ++p) {
      double grad[3];
      gn::law_energy(law, 0.3, &s[3 * p], grad);
      for (int a = 0; a < 3; ++a) {
        double sp[3] = {s[3 * p], s[3 * p + 1], s[3 * p + 2]}, sm[3] = {sp[0], sp[1], sp[2]};
        sp[a] += 1e-6;
        sm[a] -= 1e-6;
        const double fd =
            (gn::law_energy(law, 0.3, sp, nullptr) - gn::law_energy(law, 0.3, sm, nullptr)) / 2e-6;
        EXPECT_NEAR(grad[a], fd, 1e-6 * (1 + std::fabs(fd)));
      }
    }
  }
}

TEST(NeuralMtlFile, RoundTripIsExact) {
  auto w = random_weights(6, {16, 20, 12});
  w.fit_error = 1.5e-4;
  const std::string path = scratch("roundtrip.h5");
  gn::write_weights(path, w);
  const auto r = gn::read_weights(path);
  EXPECT_EQ(r.law, w.law);
  EXPECT_EQ(r.poisson_ratio, w.poisson_ratio);
  EXPECT_EQ(r.source, w.source);
  EXPECT_EQ(r.fit_error, w.fit_error);
  EXPECT_EQ(r.hidden(), w.hidden());
  EXPECT_EQ(r.flatten(), w.flatten());
}

TEST(NeuralMtlFile, BadFilesNameTheFileAndTheProblem) {
  const auto w = random_weights(7);
  const std::string good = scratch("good.h5");
  gn::write_weights(good, w);

  // Truncated file.
  const std::string cut = scratch("truncated.h5");
  {
    std::ifstream in(good, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), {});
    std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  }
  EXPECT_NE(input_error([&] { gn::read_weights(cut); }).find("truncated.h5"), std::string::npos);

  // Not HDF5 at all.
  const std::string text = scratch("text.h5");
  std::ofstream(text) << "not a weight file\n";
  EXPECT_NE(input_error([&] { gn::read_weights(text); }).find("text.h5"), std::string::npos);

  auto write_variant = [&](const std::string& name, auto&& edit) {
    gn::ArrayFile f = gn::read_array_file(good, gn::kWeightsFormat, gn::kWeightsVersion);
    edit(f);
    const std::string path = scratch(name);
    gn::write_array_file(path, f);
    return input_error([&] { gn::read_weights(path); });
  };
  std::string msg = write_variant("format.h5", [](gn::ArrayFile& f) { f.format = "other"; });
  EXPECT_NE(msg.find("format.h5"), std::string::npos) << msg;
  EXPECT_NE(msg.find("gen4d-neuralmtl"), std::string::npos) << msg;
  msg = write_variant("shape.h5", [](gn::ArrayFile& f) {
    f.arrays["layer1_W"].shape = {12, 48};  // 24 x 24 values, declared with a wrong shape
  });
  EXPECT_NE(msg.find("layer1_W"), std::string::npos) << msg;
  msg = write_variant("law.h5", [](gn::ArrayFile& f) { f.text["law"] = "jelly"; });
  EXPECT_NE(msg.find("jelly"), std::string::npos) << msg;
  msg = write_variant("nu.h5", [](gn::ArrayFile& f) { f.numbers["poisson_ratio"] = 0.7; });
  EXPECT_NE(msg.find("poisson_ratio"), std::string::npos) << msg;
  msg = write_variant("nan.h5", [](gn::ArrayFile& f) { f.arrays["layer0_b"].data[2] = NAN; });
  EXPECT_NE(msg.find("layer0_b"), std::string::npos) << msg;
  msg = write_variant("missing.h5", [](gn::ArrayFile& f) { f.arrays.erase("layer2_W"); });
  EXPECT_NE(msg.find("layer2_W"), std::string::npos) << msg;
  msg = write_variant("outputs.h5", [](gn::ArrayFile& f) {
    f.arrays["layer2_W"] = gn::NamedArray{{2, 24}, std::vector<double>(48, 0.1)};
    f.arrays["layer2_b"] = gn::NamedArray{{2}, {0.0, 0.0}};
  });
  EXPECT_NE(msg.find("3 principal strains"), std::string::npos) << msg;
  EXPECT_NE(input_error([&] { gn::read_weights(scratch("absent.h5")); }).find("absent.h5"),
            std::string::npos);
}

TEST(NeuralMtlFile, FailedWriteLeavesNoFile) {
  const auto w = random_weights(8);
  const std::string path = scratch("no_such_dir/w.h5");
  EXPECT_THROW(gn::write_weights(path, w), gen4d::RuntimeError);
  EXPECT_FALSE(std::filesystem::exists(path));
}
