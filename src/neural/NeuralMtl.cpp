// Values of the CPU lane type only pass between always-inlined functions, so no call passes one
// in an instruction-set dependent register (what GCC's -Wpsabi note is about).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wpsabi"
#endif
#include "neural/NeuralMtl.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/Error.hpp"
#include "materials/Registry.hpp"
#include "materials/FixedCorotated.hpp"
#include "materials/NeoHookean.hpp"
#include "materials/StVK.hpp"
#include "materials/Svd3.hpp"
#include "core/ParallelFor.hpp"
#include "neural/ArrayFile.hpp"

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define GEN4D_NEURAL_ISAS 1
#else
#define GEN4D_NEURAL_ISAS 0
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

}  // namespace

const std::vector<std::string>& neural_laws() {
  static const std::vector<std::string> laws = {"corotated", "neo_hookean", "stvk"};
  return laws;
}

int law_index(const std::string& law, const std::string& where) {
  const auto& laws = neural_laws();
  const auto canonical = [](const std::string& name) {  // deck names and their old spellings
    try {
      return materials::canonical_law(name, materials::Solver::Voxel);
    } catch (const InputError&) {
      return name;
    }
  };
  for (std::size_t i = 0; i < laws.size(); ++i)
    if (canonical(laws[i]) == canonical(law)) return static_cast<int>(i);
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

// The CPU lane types: GCC vectors of doubles, one per instruction-set build, each the width
// of its registers (8 lanes with AVX-512, 4 with AVX2, 2 with SSE2) so that every operation,
// the compare-selects and integer shifts of tanh included, is one instruction.
typedef double V8 __attribute__((vector_size(64)));
typedef std::int64_t V8i __attribute__((vector_size(64)));
typedef double V4 __attribute__((vector_size(32)));
typedef std::int64_t V4i __attribute__((vector_size(32)));
typedef double V2 __attribute__((vector_size(16)));
typedef std::int64_t V2i __attribute__((vector_size(16)));

template <class V, class Vi>
struct VectorLaneOps {
  static constexpr int kLanes = sizeof(V) / sizeof(double);
  GEN4D_KERNEL_INLINE static V splat(double c) { return V{} + c; }
  GEN4D_KERNEL_INLINE static V abs(const V& x) {
    return reinterpret_cast<V>(reinterpret_cast<Vi>(x) & std::int64_t{0x7fffffffffffffff});
  }
  GEN4D_KERNEL_INLINE static V min(const V& x, double c) { return x < c ? x : splat(c); }
  GEN4D_KERNEL_INLINE static V copysign(const V& mag, const V& sgn) {
    const std::int64_t sign = std::int64_t{1} << 63;
    return reinterpret_cast<V>(reinterpret_cast<Vi>(mag) | (reinterpret_cast<Vi>(sgn) & sign));
  }
  GEN4D_KERNEL_INLINE static V pow2(const V& t) {
    return reinterpret_cast<V>((reinterpret_cast<Vi>(t) << 52) + (std::int64_t{1023} << 52));
  }
};
template <>
struct LaneOps<V8> : VectorLaneOps<V8, V8i> {};
template <>
struct LaneOps<V4> : VectorLaneOps<V4, V4i> {};
template <>
struct LaneOps<V2> : VectorLaneOps<V2, V2i> {};

namespace {

//! Points [begin, end) in groups of as many points as V has lanes (the last one partial):
//! gather sigma - 1 into lanes, run the pass, scatter the outputs (each may be null).
//! Block: output rows per register block (8 accumulators leave room in the 16 vector
//! registers of SSE2 and AVX2 as in the 32 of AVX-512).
template <class V, int Block>
GEN4D_KERNEL_INLINE void run_groups(const NetView& net, std::size_t begin, std::size_t end,
                                    const double* sigma, double* psi, double* dpsi,
                                    double* strain) {
  using Ops = LaneOps<V>;
  constexpr int L = Ops::kLanes;
  alignas(64) V h[kMaxLayers + 1][kMaxWidth], g[2][kMaxWidth];
  for (std::size_t s = begin; s < end; s += L) {
    const int count = static_cast<int>(std::min<std::size_t>(L, end - s));
    const double* in = sigma + 3 * s;
    V x[3], n[3], d[3];
    for (int a = 0; a < 3; ++a) {
      x[a] = Ops::splat(0.0);
      for (int p = 0; p < count; ++p) x[a][p] = in[3 * p + a] - 1.0;
    }
    if (dpsi)
      neural_pass<Block, true>(net, x, h, g, n, d);
    else
      neural_pass<Block, false>(net, x, h, g, n, d);
    if (strain)
      for (int p = 0; p < count; ++p)
        for (int a = 0; a < 3; ++a) strain[3 * (s + p) + a] = n[a][p];
    if (psi) {
      const V e = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]) * 0.5;
      for (int p = 0; p < count; ++p) psi[s + p] = e[p];
    }
    if (dpsi)
      for (int p = 0; p < count; ++p)
        for (int a = 0; a < 3; ++a) dpsi[3 * (s + p) + a] = d[a][p];
  }
}

using GroupFn = void (*)(const NetView&, std::size_t, std::size_t, const double*, double*, double*,
                         double*);

void groups_baseline(const NetView& net, std::size_t begin, std::size_t end, const double* sigma,
                     double* psi, double* dpsi, double* strain) {
  run_groups<V2, 8>(net, begin, end, sigma, psi, dpsi, strain);
}

#if GEN4D_NEURAL_ISAS
__attribute__((target("arch=x86-64-v3"))) void groups_avx2(const NetView& net, std::size_t begin,
                                                           std::size_t end, const double* sigma,
                                                           double* psi, double* dpsi,
                                                           double* strain) {
  run_groups<V4, 8>(net, begin, end, sigma, psi, dpsi, strain);
}

__attribute__((target("arch=x86-64-v4"))) void groups_avx512(const NetView& net, std::size_t begin,
                                                             std::size_t end, const double* sigma,
                                                             double* psi, double* dpsi,
                                                             double* strain) {
  run_groups<V8, 8>(net, begin, end, sigma, psi, dpsi, strain);
}
#endif

struct CpuKernel {
  GroupFn fn;
  const char* isa;
};

//! The builds this CPU runs, the baseline first.
std::vector<CpuKernel> cpu_kernels() {
  std::vector<CpuKernel> out{{groups_baseline, "baseline"}};
#if GEN4D_NEURAL_ISAS
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"))
    out.push_back({groups_avx2, "avx2"});
  if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq") &&
      __builtin_cpu_supports("avx512cd") && __builtin_cpu_supports("avx512vl") &&
      __builtin_cpu_supports("avx512bw"))
    out.push_back({groups_avx512, "avx512"});
#endif
  return out;
}

//! The build in use: the widest, or the one GEN4D_NEURAL_ISA names (for comparisons).
CpuKernel& cpu_kernel() {
  static CpuKernel k = [] {
    const auto all = cpu_kernels();
    const char* want = std::getenv("GEN4D_NEURAL_ISA");
    for (const CpuKernel& c : all)
      if (want && want == std::string(c.isa)) return c;
    return all.back();
  }();
  return k;
}

}  // namespace

NeuralMtl::NeuralMtl(const NeuralMtlWeights& w) : law_(w.law), nu_(w.poisson_ratio) {
  w.validate("NeuralMTL weights");
  const int layers = static_cast<int>(w.layers.size());
  auto padded = [](int n) { return (n + kPad - 1) / kPad * kPad; };
  view_.layers = layers;
  view_.width[0] = padded(3);
  for (int l = 0; l < layers; ++l) {
    const Layer& L = w.layers[l];
    const int in = view_.width[l], out = padded(L.out);
    view_.width[l + 1] = out;
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
    view_.W[l] = W_[l].data();
    view_.Wt[l] = Wt_[l].data();
    view_.b[l] = b_[l].data();
  }
  // Activation: subtract the raw output at rest, computed by the same arithmetic (m0 = 0
  // while it is computed), so the strain, energy and stress at rest are exactly zero.
  const double rest[3] = {1.0, 1.0, 1.0};
  double m0[3];
  strain(1, rest, m0);
  for (int a = 0; a < 3; ++a) view_.m0[a] = m0[a];
}

const char* NeuralMtl::isa() {
  return cpu_kernel().isa;
}

std::vector<std::string> NeuralMtl::isas() {
  std::vector<std::string> out;
  for (const CpuKernel& c : cpu_kernels()) out.emplace_back(c.isa);
  return out;
}

void NeuralMtl::select_isa(const std::string& isa) {
  for (const CpuKernel& c : cpu_kernels())
    if (isa == c.isa) {
      cpu_kernel() = c;
      return;
    }
  throw std::invalid_argument("NeuralMtl::select_isa: '" + isa + "' is not available here");
}

// Each thread takes whole groups of kLanes points (a multiple of every lane width).
void NeuralMtl::evaluate(std::size_t n, const double* sigma, double* psi, double* dpsi) const {
  const GroupFn fn = cpu_kernel().fn;
  const long groups = static_cast<long>((n + kLanes - 1) / kLanes);
  exec::parallel_blocks(groups, [&](long g0, long g1) {
    fn(view_, static_cast<std::size_t>(g0) * kLanes,
       std::min(n, static_cast<std::size_t>(g1) * kLanes), sigma, psi, dpsi, nullptr);
  });
}

void NeuralMtl::strain(std::size_t n, const double* sigma, double* out) const {
  const GroupFn fn = cpu_kernel().fn;
  const long groups = static_cast<long>((n + kLanes - 1) / kLanes);
  exec::parallel_blocks(groups, [&](long g0, long g1) {
    fn(view_, static_cast<std::size_t>(g0) * kLanes,
       std::min(n, static_cast<std::size_t>(g1) * kLanes), sigma, nullptr, nullptr, out);
  });
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
