// Built with -ffp-contract=off (src/CMakeLists.txt), as the other vector kernels (Isa.hpp).
#include "forward/BlockLDLT.hpp"

#include "forward/Isa.hpp"

#include <Eigen/OrderingMethods>
#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace gen4d::forward {

void BlockLDLT::analyze(const SpMat& A) {
  if (A.rows() != A.cols() || A.rows() % 3 != 0)
    throw std::logic_error("BlockLDLT: the matrix must be square with 3 dofs per node");
  nodes_ = static_cast<int>(A.rows() / 3);
  const std::size_t n = static_cast<std::size_t>(nodes_);
  // Node graph and its AMD order.
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(static_cast<std::size_t>(A.nonZeros()) + n);
  for (int k = 0; k < A.outerSize(); ++k)
    for (SpMat::InnerIterator it(A, k); it; ++it)
      t.emplace_back(static_cast<int>(it.row() / 3), static_cast<int>(it.col() / 3), 1.0);
  for (int i = 0; i < nodes_; ++i) t.emplace_back(i, i, 1.0);
  SpMat G(nodes_, nodes_);
  G.setFromTriplets(t.begin(), t.end());
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> pinv;
  Eigen::AMDOrdering<int> amd;
  amd(G, pinv);
  perm_.assign(n, 0);
  iperm_.assign(n, 0);
  for (int i = 0; i < nodes_; ++i) perm_[static_cast<std::size_t>(pinv.indices()[i])] = i;
  for (std::size_t o = 0; o < n; ++o)
    iperm_[static_cast<std::size_t>(perm_[o])] = static_cast<int>(o);
  // Symbolic elimination on the permuted node graph: the rows of column K are its neighbours
  // after K, and the rows of every column whose parent (first row) is K, minus K.
  std::vector<std::vector<int>> adj(n), rows(n), children(n);
  for (int k = 0; k < G.outerSize(); ++k)
    for (SpMat::InnerIterator it(G, k); it; ++it) {
      const int i = perm_[static_cast<std::size_t>(it.row())];
      const int j = perm_[static_cast<std::size_t>(it.col())];
      if (i > j) adj[static_cast<std::size_t>(j)].push_back(i);
    }
  for (std::size_t K = 0; K < n; ++K) {
    std::vector<int>& r = rows[K];
    r = adj[K];
    for (int c : children[K])
      for (int i : rows[static_cast<std::size_t>(c)])
        if (i > static_cast<int>(K)) r.push_back(i);
    std::sort(r.begin(), r.end());
    r.erase(std::unique(r.begin(), r.end()), r.end());
    if (!r.empty()) children[static_cast<std::size_t>(r.front())].push_back(static_cast<int>(K));
  }
  start_.assign(n + 1, 0);
  row_.clear();
  row_blocks_.assign(n, {});
  for (std::size_t K = 0; K < n; ++K) {
    start_[K] = static_cast<int>(row_.size());
    for (int i : rows[K]) {
      row_blocks_[static_cast<std::size_t>(i)].emplace_back(static_cast<int>(K),
                                                            static_cast<int>(row_.size()));
      row_.push_back(i);
    }
  }
  start_[n] = static_cast<int>(row_.size());
  L_.assign(12 * row_.size(), 0.0);
  LT_.assign(12 * row_.size(), 0.0);
  MT_.assign(12 * row_.size(), 0.0);
  Dinv_.assign(9 * n, 0.0);
  slot_.assign(n, -1);
  y_.assign(4 * n, 0.0);
}

namespace {

//! Inverse of a 3x3 matrix (row-major); false when singular or not finite.
bool invert3(const double* a, double* inv) {
  const double c00 = a[4] * a[8] - a[5] * a[7], c01 = a[5] * a[6] - a[3] * a[8],
               c02 = a[3] * a[7] - a[4] * a[6];
  const double det = a[0] * c00 + a[1] * c01 + a[2] * c02;
  double scale = 0;
  for (int i = 0; i < 9; ++i) scale = std::max(scale, std::abs(a[i]));
  if (!std::isfinite(det) || !(std::abs(det) > 1e-13 * scale * scale * scale)) return false;
  const double r = 1.0 / det;
  inv[0] = c00 * r, inv[1] = (a[2] * a[7] - a[1] * a[8]) * r,
  inv[2] = (a[1] * a[5] - a[2] * a[4]) * r;
  inv[3] = c01 * r, inv[4] = (a[0] * a[8] - a[2] * a[6]) * r,
  inv[5] = (a[2] * a[3] - a[0] * a[5]) * r;
  inv[6] = c02 * r, inv[7] = (a[1] * a[6] - a[0] * a[7]) * r,
  inv[8] = (a[0] * a[4] - a[1] * a[3]) * r;
  return true;
}

// s * (b0 b1 b2 b3)^T for the block row or column at p (4 values).
GEN4D_ALWAYS_INLINE V4 scaled(const double* p, double s) {
  return load4(p) * s;
}

// The left-looking updates of column K: W_I -= L_IJ M_KJ^T for every (J, block of L_KJ) in
// rb and the blocks of column J from row K down; row a of the product, lane b, is
// (l_a0 m_b0 + l_a1 m_b1) + l_a2 m_b2, as the scalar 3x3 product sums it.
GEN4D_ALWAYS_INLINE void updates_body(const std::pair<int, int>* rb, std::size_t nrb,
                                      const int* start, const int* row, const double* L,
                                      const double* MT, const int* slot, int K, double* W,
                                      double* Wd) {
  for (std::size_t r = 0; r < nrb; ++r) {
    const int J = rb[r].first, pKJ = rb[r].second;
    const double* mt = MT + 12 * static_cast<std::size_t>(pKJ);
    const V4 m0 = load4(mt), m1 = load4(mt + 4), m2 = load4(mt + 8);
    const int pend = start[J + 1];
    for (int p = pKJ; p < pend; ++p) {
      const int I = row[p];
      double* dst = I == K ? Wd : W + 12 * static_cast<std::size_t>(slot[I]);
      const double* l = L + 12 * static_cast<std::size_t>(p);
      for (int a = 0; a < 3; ++a) {
        const V4 t = m0 * l[4 * a] + m1 * l[4 * a + 1] + m2 * l[4 * a + 2];
        store4(dst + 4 * a, load4(dst + 4 * a) - t);
      }
    }
  }
}

// Column K's blocks from its updated W: M_IK = W_I (kept transposed), L_IK = W_I D_K^-1 (row a,
// lane b: (w_a0 d_0b + w_a1 d_1b) + w_a2 d_2b) and its transpose.
GEN4D_ALWAYS_INLINE void finish_body(const double* W, std::size_t nb, const double* dinv, double* L,
                                     double* LT, double* MT) {
  alignas(32) const double d[12] = {dinv[0], dinv[1], dinv[2], 0,       dinv[3], dinv[4],
                                    dinv[5], 0,       dinv[6], dinv[7], dinv[8], 0};
  const V4 d0 = load4(d), d1 = load4(d + 4), d2 = load4(d + 8);
  for (std::size_t q = 0; q < nb; ++q) {
    const double* w = W + 12 * q;
    double* l = L + 12 * q;
    double* lt = LT + 12 * q;
    double* mt = MT + 12 * q;
    for (int a = 0; a < 3; ++a)
      store4(l + 4 * a, d0 * w[4 * a] + d1 * w[4 * a + 1] + d2 * w[4 * a + 2]);
    for (int a = 0; a < 3; ++a) {
      l[4 * a + 3] = 0;
      for (int c = 0; c < 3; ++c) lt[4 * c + a] = l[4 * a + c], mt[4 * c + a] = w[4 * a + c];
    }
    lt[3] = lt[7] = lt[11] = mt[3] = mt[7] = mt[11] = 0;
  }
}

// L z = b, D w = z, L^T x = w on the permuted, padded vector y (4 values per node). Forward:
// lane a of column c of L; backward: lane b of row a; each lane sums as the scalar product.
// Without AVX (kVector false) the three lanes are scalars: the baseline build's 4-lane vectors
// are pairs of 2-lane ones, and its substitutions ran 1.7x slower so (bench_diagnose).
template <bool kVector>
GEN4D_ALWAYS_INLINE void solve_body(int nodes, const int* st, const int* rw, const double* L,
                                    const double* LT, const double* Dinv, double* y) {
  for (int K = 0; K < nodes; ++K) {
    const double y0 = y[4 * K], y1 = y[4 * K + 1], y2 = y[4 * K + 2];
    for (int j = st[K]; j < st[K + 1]; ++j) {
      double* yi = y + 4 * rw[j];
      if constexpr (kVector) {
        const double* lt = LT + 12 * static_cast<std::size_t>(j);
        store4(yi, load4(yi) - (scaled(lt, y0) + scaled(lt + 4, y1) + scaled(lt + 8, y2)));
      } else {  // the rows of L: one array read by both substitutions
        const double* l = L + 12 * static_cast<std::size_t>(j);
        for (int a = 0; a < 3; ++a) yi[a] -= l[4 * a] * y0 + l[4 * a + 1] * y1 + l[4 * a + 2] * y2;
      }
    }
  }
  for (int K = 0; K < nodes; ++K) {
    const double* d = Dinv + 9 * K;
    double* yk = y + 4 * K;
    const double y0 = yk[0], y1 = yk[1], y2 = yk[2];
    yk[0] = d[0] * y0 + d[1] * y1 + d[2] * y2;
    yk[1] = d[3] * y0 + d[4] * y1 + d[5] * y2;
    yk[2] = d[6] * y0 + d[7] * y1 + d[8] * y2;
  }
  for (int K = nodes - 1; K >= 0; --K) {
    if constexpr (kVector) {
      V4 acc = load4(y + 4 * K);
      for (int j = st[K]; j < st[K + 1]; ++j) {
        const double* yi = y + 4 * rw[j];
        const double* l = L + 12 * static_cast<std::size_t>(j);
        acc = acc - (scaled(l, yi[0]) + scaled(l + 4, yi[1]) + scaled(l + 8, yi[2]));
      }
      store4(y + 4 * K, acc);
    } else {
      double acc[3] = {y[4 * K], y[4 * K + 1], y[4 * K + 2]};
      for (int j = st[K]; j < st[K + 1]; ++j) {
        const double* yi = y + 4 * rw[j];
        const double* l = L + 12 * static_cast<std::size_t>(j);
        for (int b = 0; b < 3; ++b) acc[b] -= l[b] * yi[0] + l[4 + b] * yi[1] + l[8 + b] * yi[2];
      }
      for (int b = 0; b < 3; ++b) y[4 * K + b] = acc[b];
    }
  }
}

// One entry point per instruction set, each the same source.
struct Kernels {
  const char* isa;
  void (*updates)(const std::pair<int, int>*, std::size_t, const int*, const int*, const double*,
                  const double*, const int*, int, double*, double*);
  void (*finish)(const double*, std::size_t, const double*, double*, double*, double*);
  void (*solve)(int, const int*, const int*, const double*, const double*, const double*, double*);
};

#define GEN4D_BLOCK_KERNELS(name, attr, vector)                                                \
  attr void updates_##name(const std::pair<int, int>* rb, std::size_t nrb, const int* start,   \
                           const int* row, const double* L, const double* MT, const int* slot, \
                           int K, double* W, double* Wd) {                                     \
    updates_body(rb, nrb, start, row, L, MT, slot, K, W, Wd);                                  \
  }                                                                                            \
  attr void finish_##name(const double* W, std::size_t nb, const double* dinv, double* L,      \
                          double* LT, double* MT) {                                            \
    finish_body(W, nb, dinv, L, LT, MT);                                                       \
  }                                                                                            \
  attr void solve_##name(int nodes, const int* st, const int* rw, const double* L,             \
                         const double* LT, const double* Dinv, double* y) {                    \
    solve_body<vector>(nodes, st, rw, L, LT, Dinv, y);                                         \
  }                                                                                            \
  const Kernels k_##name{#name, updates_##name, finish_##name, solve_##name};

GEN4D_BLOCK_KERNELS(baseline, , false)
#if GEN4D_X86_ISAS
GEN4D_BLOCK_KERNELS(avx2, __attribute__((target("avx2"))), true)
#endif
#undef GEN4D_BLOCK_KERNELS

#if GEN4D_X86_ISAS
IsaDispatch<Kernels> g_kernels({&k_baseline, &k_avx2}, "BlockLDLT");
#else
IsaDispatch<Kernels> g_kernels({&k_baseline}, "BlockLDLT");
#endif

}  // namespace

std::vector<std::string> BlockLDLT::isas() {
  return g_kernels.isas();
}

std::string BlockLDLT::isa() {
  return g_kernels->isa;
}

void BlockLDLT::set_isa(const std::string& isa) {
  g_kernels.set(isa);
}

bool BlockLDLT::factorize(const SpMat& A) {
  const std::size_t n = static_cast<std::size_t>(nodes_);
  const Kernels& kern = *g_kernels;
  for (std::size_t K = 0; K < n; ++K) {
    const int b0 = start_[K], b1 = start_[K + 1];
    const std::size_t nb = static_cast<std::size_t>(b1 - b0);
    // W: 12 values per block of column K, then 12 for the diagonal block.
    W_.assign(12 * (nb + 1), 0.0);
    double* W = W_.data();
    double* Wd = W + 12 * nb;
    for (int p = b0; p < b1; ++p)
      slot_[static_cast<std::size_t>(row_[static_cast<std::size_t>(p)])] = p - b0;
    // Gather A's column block K (rows at or below its diagonal block, new numbering).
    const int old = iperm_[K];
    for (int b = 0; b < 3; ++b)
      for (SpMat::InnerIterator it(A, 3 * old + b); it; ++it) {
        const int I = perm_[static_cast<std::size_t>(it.row() / 3)];
        const int a = static_cast<int>(it.row() % 3);
        if (I < static_cast<int>(K)) continue;
        const int sl =
            I == static_cast<int>(K) ? static_cast<int>(nb) : slot_[static_cast<std::size_t>(I)];
        if (sl < 0) throw std::logic_error("BlockLDLT: entry outside the analysed pattern");
        W[12 * static_cast<std::size_t>(sl) + static_cast<std::size_t>(4 * a + b)] += it.value();
      }
    // Left-looking updates from every column J with a block in row K:
    // W_I -= L_IJ M_KJ^T for the blocks of J from row K down (M_KJ = L_KJ D_J).
    const auto& rb = row_blocks_[K];
    kern.updates(rb.data(), rb.size(), start_.data(), row_.data(), L_.data(), MT_.data(),
                 slot_.data(), static_cast<int>(K), W, Wd);
    for (int p = b0; p < b1; ++p)
      slot_[static_cast<std::size_t>(row_[static_cast<std::size_t>(p)])] = -1;
    // D_K (symmetrised against rounding) and its inverse.
    double D[9];
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) D[3 * a + b] = 0.5 * (Wd[4 * a + b] + Wd[4 * b + a]);
    double* dinv = &Dinv_[9 * K];
    if (!invert3(D, dinv)) return false;
    const std::size_t o = 12 * static_cast<std::size_t>(b0);
    kern.finish(W, nb, dinv, &L_[o], &LT_[o], &MT_[o]);
  }
  return true;
}

void BlockLDLT::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) const {
  double* y = y_.data();
  const std::size_t n = static_cast<std::size_t>(nodes_);
  for (std::size_t o = 0; o < n; ++o)
    for (int a = 0; a < 3; ++a) y[4 * perm_[o] + a] = b[static_cast<Eigen::Index>(3 * o) + a];
  g_kernels->solve(nodes_, start_.data(), row_.data(), L_.data(), LT_.data(), Dinv_.data(), y);
  x.resize(3 * nodes_);
  for (std::size_t o = 0; o < n; ++o)
    for (int a = 0; a < 3; ++a) x[static_cast<Eigen::Index>(3 * o) + a] = y[4 * perm_[o] + a];
}

}  // namespace gen4d::forward
