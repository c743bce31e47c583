#include "neural/NeuralMtl.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <stdexcept>

#include "core/Error.hpp"
#include "materials/FixedCorotated.hpp"
#include "materials/NeoHookean.hpp"
#include "materials/StVK.hpp"
#include "materials/Svd3.hpp"
#include "neural/ArrayFile.hpp"

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define GEN4D_KERNEL_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define GEN4D_KERNEL_CLONES
#endif

namespace gen4d::neural {
namespace {

using materials::Mat3;

template <class M>
double principal(const M& m, const double sigma[3], double grad[3]) {
  Mat3 F{};
  for (int a = 0; a < 3; ++a) F.a[4 * a] = sigma[a];
  Mat3 P;
  const double psi = m.energy_and_pk1(F, P);
  // For an isotropic energy P(diag(sigma)) is diagonal with entries d psi / d sigma_i.
  if (grad)
    for (int a = 0; a < 3; ++a) grad[a] = P.a[4 * a];
  return psi;
}

// exp for the tanh below, written so that a loop over lanes vectorises (no library call,
// no branches): x = n ln2 + r with |r| <= ln2/2, e^r by its degree-12 Taylor polynomial
// (truncation < 2e-16 relative), 2^n assembled in the exponent bits. Valid for |x| <= 700.
inline double exp_lane(double x) {
  constexpr double kShift = 6755399441055744.0;  // 1.5 * 2^52: adding it rounds to an integer
  constexpr double kLog2e = 1.4426950408889634, kLn2Hi = 6.93147180369123816490e-01,
                   kLn2Lo = 1.90821492927058770002e-10;
  const double t = x * kLog2e + kShift;
  const double nf = t - kShift;
  const double r = (x - nf * kLn2Hi) - nf * kLn2Lo;
  double p = 1.0 / 479001600.0;
  p = p * r + 1.0 / 39916800.0;
  p = p * r + 1.0 / 3628800.0;
  p = p * r + 1.0 / 362880.0;
  p = p * r + 1.0 / 40320.0;
  p = p * r + 1.0 / 5040.0;
  p = p * r + 1.0 / 720.0;
  p = p * r + 1.0 / 120.0;
  p = p * r + 1.0 / 24.0;
  p = p * r + 1.0 / 6.0;
  p = p * r + 0.5;
  p = p * r + 1.0;
  p = p * r + 1.0;
  std::uint64_t bits;
  std::memcpy(&bits, &t, sizeof bits);  // low bits hold n (two's complement, mod 2^51)
  bits = (bits << 52) + (std::uint64_t{1023} << 52);
  double scale;
  std::memcpy(&scale, &bits, sizeof scale);
  return p * scale;
}

//! tanh(a) = sign(a) (1 - 2 / (e^{2|a|} + 1)); absolute error ~2e-16. |a| is capped at 20,
//! where tanh is 1 to double precision.
inline double tanh_lane(double a) {
  const double s = std::min(std::fabs(a), 20.0);
  const double y = 1.0 - 2.0 / (exp_lane(2.0 * s) + 1.0);
  return std::copysign(y, a);
}

}  // namespace

const std::vector<std::string>& neural_laws() {
  static const std::vector<std::string> laws = {"corotated", "neo_hookean", "stvk"};
  return laws;
}

int law_index(const std::string& law, const std::string& where) {
  const auto& laws = neural_laws();
  for (std::size_t i = 0; i < laws.size(); ++i)
    if (laws[i] == law) return static_cast<int>(i);
  throw InputError(where + ": law '" + law +
                   "' has no NeuralMTL (known: corotated, neo_hookean, stvk)");
}

double law_energy(int law, double nu, const double sigma[3], double grad[3]) {
  switch (law) {
    case 0:
      return principal(materials::FixedCorotated::from_young_poisson(1.0, nu), sigma, grad);
    case 1:
      return principal(materials::NeoHookean::from_young_poisson(1.0, nu), sigma, grad);
    case 2:
      return principal(materials::StVK::from_young_poisson(1.0, nu), sigma, grad);
    default:
      throw std::invalid_argument("law_energy: bad law index");
  }
}

// ---------------------------------------------------------------------------------------------
// Weights

NeuralMtlWeights NeuralMtlWeights::architecture(const std::vector<int>& hidden) {
  NeuralMtlWeights w;
  int in = 3;
  for (std::size_t l = 0; l <= hidden.size(); ++l) {
    const int out = l < hidden.size() ? hidden[l] : 3;
    Layer layer;
    layer.in = in;
    layer.out = out;
    layer.W.assign(static_cast<std::size_t>(in) * out, 0.0);
    layer.b.assign(out, 0.0);
    w.layers.push_back(std::move(layer));
    in = out;
  }
  return w;
}

std::vector<int> NeuralMtlWeights::hidden() const {
  std::vector<int> h;
  for (std::size_t l = 0; l + 1 < layers.size(); ++l) h.push_back(layers[l].out);
  return h;
}

std::size_t NeuralMtlWeights::parameter_count() const {
  std::size_t n = 0;
  for (const Layer& l : layers) n += l.W.size() + l.b.size();
  return n;
}

std::vector<double> NeuralMtlWeights::flatten() const {
  std::vector<double> flat;
  flat.reserve(parameter_count());
  for (const Layer& l : layers) {
    flat.insert(flat.end(), l.W.begin(), l.W.end());
    flat.insert(flat.end(), l.b.begin(), l.b.end());
  }
  return flat;
}

void NeuralMtlWeights::unflatten(const std::vector<double>& flat) {
  if (flat.size() != parameter_count())
    throw std::invalid_argument("NeuralMtlWeights::unflatten: " + std::to_string(flat.size()) +
                                " values for " + std::to_string(parameter_count()) + " parameters");
  auto it = flat.begin();
  for (Layer& l : layers) {
    std::copy(it, it + static_cast<long>(l.W.size()), l.W.begin());
    it += static_cast<long>(l.W.size());
    std::copy(it, it + static_cast<long>(l.b.size()), l.b.begin());
    it += static_cast<long>(l.b.size());
  }
}

void NeuralMtlWeights::validate(const std::string& where) const {
  law_index(law, where);
  if (!(poisson_ratio >= 0.0 && poisson_ratio < 0.5))
    throw InputError(where + ": poisson_ratio " + std::to_string(poisson_ratio) +
                     " is outside [0, 0.5)");
  if (layers.size() < 2 || layers.size() > static_cast<std::size_t>(kMaxLayers))
    throw InputError(where + ": a NeuralMTL needs 2 to " + std::to_string(kMaxLayers) +
                     " layers, found " + std::to_string(layers.size()));
  int in = 3;
  for (std::size_t l = 0; l < layers.size(); ++l) {
    const Layer& L = layers[l];
    const std::string name = where + ": layer " + std::to_string(l);
    if (L.in != in)
      throw InputError(name + " takes " + std::to_string(L.in) + " inputs, expected " +
                       std::to_string(in));
    if (L.out < 1 || L.out > kMaxWidth)
      throw InputError(name + " has width " + std::to_string(L.out) + " (1 to " +
                       std::to_string(kMaxWidth) + " allowed)");
    if (L.W.size() != static_cast<std::size_t>(L.in) * L.out ||
        L.b.size() != static_cast<std::size_t>(L.out))
      throw InputError(name + " has inconsistent weight or bias sizes");
    for (double v : L.W)
      if (!std::isfinite(v)) throw InputError(name + " holds a non-finite weight");
    for (double v : L.b)
      if (!std::isfinite(v)) throw InputError(name + " holds a non-finite bias");
    in = L.out;
  }
  if (in != 3)
    throw InputError(where + ": the last layer has " + std::to_string(in) +
                     " outputs, a NeuralMTL predicts 3 principal strains");
}

void write_weights(const std::string& path, const NeuralMtlWeights& w) {
  w.validate(path);
  ArrayFile f;
  f.format = kWeightsFormat;
  f.format_version = kWeightsVersion;
  f.text["law"] = w.law;
  f.text["activation"] = "tanh";
  f.text["source"] = w.source;
  f.numbers["poisson_ratio"] = w.poisson_ratio;
  f.numbers["fit_error"] = w.fit_error;
  f.numbers["layers"] = static_cast<double>(w.layers.size());
  for (std::size_t l = 0; l < w.layers.size(); ++l) {
    const Layer& L = w.layers[l];
    const std::string p = "layer" + std::to_string(l);
    f.arrays[p + "_W"] = NamedArray{{L.out, L.in}, L.W};
    f.arrays[p + "_b"] = NamedArray{{L.out}, L.b};
  }
  write_array_file(path, f);
}

NeuralMtlWeights read_weights(const std::string& path) {
  const ArrayFile f = read_array_file(path, kWeightsFormat, kWeightsVersion);
  NeuralMtlWeights w;
  w.law = f.text_attr("law", path);
  if (f.text_attr("activation", path) != "tanh")
    throw InputError(path + ": activation '" + f.text_attr("activation", path) +
                     "' is not supported (tanh)");
  auto src = f.text.find("source");
  w.source = src == f.text.end() ? "" : src->second;
  w.poisson_ratio = f.number_attr("poisson_ratio", path);
  auto fit = f.numbers.find("fit_error");
  w.fit_error = fit == f.numbers.end() ? -1.0 : fit->second;
  const double layers = f.number_attr("layers", path);
  if (!(layers >= 2 && layers <= kMaxLayers && layers == std::floor(layers)))
    throw InputError(path + ": attribute 'layers' = " + std::to_string(layers) +
                     " is not a layer count in [2, " + std::to_string(kMaxLayers) + "]");
  int in = 3;
  for (int l = 0; l < static_cast<int>(layers); ++l) {
    const std::string p = "layer" + std::to_string(l);
    const NamedArray& b = f.array(p + "_b", {-1}, path);
    const long out = b.shape[0];
    if (out < 1 || out > kMaxWidth)
      throw InputError(path + ": dataset '" + p + "_b' has width " + std::to_string(out) +
                       " (1 to " + std::to_string(kMaxWidth) + " allowed)");
    const NamedArray& W = f.array(p + "_W", {out, in}, path);
    Layer L;
    L.in = in;
    L.out = static_cast<int>(out);
    L.W = W.data;
    L.b = b.data;
    w.layers.push_back(std::move(L));
    in = static_cast<int>(out);
  }
  w.validate(path);
  return w;
}

// ---------------------------------------------------------------------------------------------
// Fused kernel

NeuralMtl::NeuralMtl(const NeuralMtlWeights& w) : law_(w.law), nu_(w.poisson_ratio) {
  w.validate("NeuralMTL weights");
  layers_ = static_cast<int>(w.layers.size());
  // Widths are padded to multiples of kBlock with zero weights and biases: a padded unit
  // computes tanh(0) = 0 and feeds nothing forward or back, so results are unchanged while
  // every loop runs over whole register blocks.
  auto padded = [](int n) { return (n + kBlock - 1) / kBlock * kBlock; };
  width_[0] = padded(3);
  for (int l = 0; l < layers_; ++l) {
    const Layer& L = w.layers[l];
    const int in = width_[l], out = padded(L.out);
    width_[l + 1] = out;
    W_[l].assign(static_cast<std::size_t>(out) * in, 0.0);
    Wt_[l].assign(static_cast<std::size_t>(out) * in, 0.0);
    b_[l].assign(out, 0.0);
    for (int j = 0; j < L.out; ++j) {
      b_[l][j] = L.b[j];
      for (int i = 0; i < L.in; ++i) {
        W_[l][static_cast<std::size_t>(j) * in + i] = L.W[j * L.in + i];
        Wt_[l][static_cast<std::size_t>(i) * out + j] = L.W[j * L.in + i];
      }
    }
  }
  // Activation: subtract the raw output at rest, computed by the same arithmetic, so the
  // strain, energy and stress at rest are exactly zero.
  const double rest[3] = {1.0, 1.0, 1.0};
  strain(1, rest, m0_.data());  // through the same clone as every later call
}

namespace {
//! out[j][p] = bias[j] + sum_i M[j * in + i] x[i][p] for j < out (a multiple of kBlock):
//! kBlock rows at a time so each loaded x[i] feeds kBlock x kLanes multiply-adds.
template <int Block, int L>
__attribute__((always_inline)) inline void dense(int in, int out, const double* M,
                                                 const double* bias, const double (*x)[L],
                                                 double (*y)[L]) {
  for (int j0 = 0; j0 < out; j0 += Block) {
    alignas(64) double acc[Block][L];
    for (int r = 0; r < Block; ++r)
      for (int p = 0; p < L; ++p) acc[r][p] = bias ? bias[j0 + r] : 0.0;
    for (int i = 0; i < in; ++i)
      for (int r = 0; r < Block; ++r) {
        const double w = M[(j0 + r) * in + i];
        for (int p = 0; p < L; ++p) acc[r][p] += w * x[i][p];
      }
    for (int r = 0; r < Block; ++r)
      for (int p = 0; p < L; ++p) y[j0 + r][p] = acc[r][p];
  }
}
}  // namespace

template <bool Backward>
__attribute__((always_inline)) inline void NeuralMtl::lanes(int count, const double* sigma,
                                                            double* psi, double* dpsi,
                                                            double* strain) const {
  constexpr int L = kLanes;
  alignas(64) double h[kMaxLayers + 1][kMaxWidth][L];  // post-activation values per layer
  for (int a = 0; a < width_[0]; ++a)
    for (int p = 0; p < L; ++p) h[0][a][p] = a < 3 && p < count ? sigma[3 * p + a] - 1.0 : 0.0;
  for (int l = 0; l < layers_; ++l) {
    const int in = width_[l], out = width_[l + 1];
    dense<kBlock, L>(in, out, W_[l].data(), b_[l].data(), h[l], h[l + 1]);
    if (l == layers_ - 1)
      for (int j = 0; j < 3; ++j)
        for (int p = 0; p < L; ++p) h[l + 1][j][p] -= m0_[j];
    else
      for (int j = 0; j < out; ++j)
        for (int p = 0; p < L; ++p) h[l + 1][j][p] = tanh_lane(h[l + 1][j][p]);
  }
  const double(*n)[L] = h[layers_];
  if (strain)
    for (int p = 0; p < count; ++p)
      for (int a = 0; a < 3; ++a) strain[3 * p + a] = n[a][p];
  if (psi)
    for (int p = 0; p < count; ++p)
      psi[p] = 0.5 * (n[0][p] * n[0][p] + n[1][p] * n[1][p] + n[2][p] * n[2][p]);
  if constexpr (Backward) {
    // Reverse pass of psi = |n|^2 / 2: g starts at n (padded entries 0) and goes back
    // through each layer: g_in = W^T g_out, times tanh' = 1 - h^2 below the last layer.
    alignas(64) double g[2][kMaxWidth][L];
    for (int a = 0; a < width_[layers_]; ++a)
      for (int p = 0; p < L; ++p) g[0][a][p] = a < 3 ? n[a][p] : 0.0;
    int cur = 0;
    for (int l = layers_ - 1; l >= 0; --l) {
      const int in = width_[l], out = width_[l + 1];
      dense<kBlock, L>(out, in, Wt_[l].data(), nullptr, g[cur], g[1 - cur]);
      cur = 1 - cur;
      if (l > 0)
        for (int i = 0; i < in; ++i)
          for (int p = 0; p < L; ++p) g[cur][i][p] *= 1.0 - h[l][i][p] * h[l][i][p];
    }
    for (int p = 0; p < count; ++p)
      for (int a = 0; a < 3; ++a) dpsi[3 * p + a] = g[cur][a][p];
  }
}

// The batch loops are compiled twice: for x86-64-v3 (AVX2 + FMA), picked at load time where
// the CPU has it, and for the baseline x86-64 (SSE2) everywhere else; lanes() is inlined into
// each clone.
GEN4D_KERNEL_CLONES void NeuralMtl::evaluate(std::size_t n, const double* sigma, double* psi,
                                             double* dpsi) const {
  for (std::size_t s = 0; s < n; s += kLanes) {
    const int count = static_cast<int>(std::min<std::size_t>(kLanes, n - s));
    if (dpsi)
      lanes<true>(count, sigma + 3 * s, psi ? psi + s : nullptr, dpsi + 3 * s, nullptr);
    else
      lanes<false>(count, sigma + 3 * s, psi ? psi + s : nullptr, nullptr, nullptr);
  }
}

GEN4D_KERNEL_CLONES void NeuralMtl::strain(std::size_t n, const double* sigma, double* out) const {
  for (std::size_t s = 0; s < n; s += kLanes) {
    const int count = static_cast<int>(std::min<std::size_t>(kLanes, n - s));
    lanes<false>(count, sigma + 3 * s, nullptr, nullptr, out + 3 * s);
  }
}

// ---------------------------------------------------------------------------------------------
// Material form

double NeuralMaterial::energy_and_pk1_cell(const double* F, double* P, int count) const {
  constexpr int L = NeuralMtl::kLanes;
  Mat3 U[L], V[L];
  double sigma[3 * L] = {}, psi[L], grad[3 * L];
  for (int p = 0; p < count; ++p) {
    Mat3 Fm;
    std::memcpy(Fm.a, F + 9 * p, sizeof Fm.a);
    materials::Vec3 s;
    materials::svd3(Fm, U[p], s, V[p]);
    for (int a = 0; a < 3; ++a) sigma[3 * p + a] = s.v[a];
  }
  net->evaluate(static_cast<std::size_t>(count), sigma, psi, grad);
  double total = 0;
  for (int p = 0; p < count; ++p) {
    // P = E U diag(grad) V^T
    double* out = P + 9 * p;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        double v = 0;
        for (int a = 0; a < 3; ++a) v += U[p].a[3 * r + a] * grad[3 * p + a] * V[p].a[3 * c + a];
        out[3 * r + c] = youngs_modulus * v;
      }
    total += youngs_modulus * psi[p];
  }
  return total;
}

double NeuralMaterial::energy_and_pk1(const Mat3& F, Mat3& P) const {
  return energy_and_pk1_cell(F.a, P.a, 1);
}

}  // namespace gen4d::neural
