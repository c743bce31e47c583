#include "diagnose/BlockLDLT.hpp"

#include <Eigen/OrderingMethods>
#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace gen4d::diagnose {

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
  L_.assign(9 * row_.size(), 0.0);
  M_.assign(9 * row_.size(), 0.0);
  Dinv_.assign(9 * n, 0.0);
  slot_.assign(n, -1);
  y_.resize(3 * nodes_);
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

}  // namespace

bool BlockLDLT::factorize(const SpMat& A) {
  const std::size_t n = static_cast<std::size_t>(nodes_);
  for (std::size_t K = 0; K < n; ++K) {
    const int b0 = start_[K], b1 = start_[K + 1];
    const std::size_t nb = static_cast<std::size_t>(b1 - b0);
    // W: 9 values per block of column K, then 9 for the diagonal block.
    W_.assign(9 * (nb + 1), 0.0);
    double* W = W_.data();
    double* Wd = W + 9 * nb;
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
        W[9 * static_cast<std::size_t>(sl) + static_cast<std::size_t>(3 * a + b)] += it.value();
      }
    // Left-looking updates from every column J with a block in row K:
    // W_I -= L_IJ M_KJ^T for the blocks of J from row K down (M_KJ = L_KJ D_J).
    for (const auto& [J, pKJ] : row_blocks_[K]) {
      const double* mk = &M_[9 * static_cast<std::size_t>(pKJ)];
      for (int p = pKJ; p < start_[static_cast<std::size_t>(J) + 1]; ++p) {
        const int I = row_[static_cast<std::size_t>(p)];
        double* dst = I == static_cast<int>(K)
                          ? Wd
                          : W + 9 * static_cast<std::size_t>(slot_[static_cast<std::size_t>(I)]);
        const double* l = &L_[9 * static_cast<std::size_t>(p)];
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b)
            dst[3 * a + b] -=
                l[3 * a] * mk[3 * b] + l[3 * a + 1] * mk[3 * b + 1] + l[3 * a + 2] * mk[3 * b + 2];
      }
    }
    for (int p = b0; p < b1; ++p)
      slot_[static_cast<std::size_t>(row_[static_cast<std::size_t>(p)])] = -1;
    // D_K (symmetrised against rounding) and its inverse.
    double D[9];
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) D[3 * a + b] = 0.5 * (Wd[3 * a + b] + Wd[3 * b + a]);
    double* dinv = &Dinv_[9 * K];
    if (!invert3(D, dinv)) return false;
    // M_IK = W_I, L_IK = M_IK D_K^-1.
    for (int p = b0; p < b1; ++p) {
      const double* w = W + 9 * static_cast<std::size_t>(p - b0);
      double* m = &M_[9 * static_cast<std::size_t>(p)];
      double* l = &L_[9 * static_cast<std::size_t>(p)];
      for (int i = 0; i < 9; ++i) m[i] = w[i];
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b)
          l[3 * a + b] =
              w[3 * a] * dinv[b] + w[3 * a + 1] * dinv[3 + b] + w[3 * a + 2] * dinv[6 + b];
    }
  }
  return true;
}

void BlockLDLT::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) const {
  double* y = y_.data();
  const std::size_t n = static_cast<std::size_t>(nodes_);
  for (std::size_t o = 0; o < n; ++o)
    for (int a = 0; a < 3; ++a) y[3 * perm_[o] + a] = b[static_cast<Eigen::Index>(3 * o) + a];
  const int* st = start_.data();
  const int* rw = row_.data();
  const double* L = L_.data();
  // L z = b (unit block-lower).
  for (int K = 0; K < nodes_; ++K) {
    const double y0 = y[3 * K], y1 = y[3 * K + 1], y2 = y[3 * K + 2];
    for (int j = st[K]; j < st[K + 1]; ++j) {
      double* yi = y + 3 * rw[j];
      const double* l = L + 9 * j;
      yi[0] -= l[0] * y0 + l[1] * y1 + l[2] * y2;
      yi[1] -= l[3] * y0 + l[4] * y1 + l[5] * y2;
      yi[2] -= l[6] * y0 + l[7] * y1 + l[8] * y2;
    }
  }
  // D w = z.
  for (std::size_t K = 0; K < n; ++K) {
    const double* d = &Dinv_[9 * K];
    double* yk = y + 3 * K;
    const double y0 = yk[0], y1 = yk[1], y2 = yk[2];
    yk[0] = d[0] * y0 + d[1] * y1 + d[2] * y2;
    yk[1] = d[3] * y0 + d[4] * y1 + d[5] * y2;
    yk[2] = d[6] * y0 + d[7] * y1 + d[8] * y2;
  }
  // L^T x = w.
  for (int K = nodes_ - 1; K >= 0; --K) {
    double y0 = y[3 * K], y1 = y[3 * K + 1], y2 = y[3 * K + 2];
    for (int j = st[K]; j < st[K + 1]; ++j) {
      const double* yi = y + 3 * rw[j];
      const double* l = L + 9 * j;
      y0 -= l[0] * yi[0] + l[3] * yi[1] + l[6] * yi[2];
      y1 -= l[1] * yi[0] + l[4] * yi[1] + l[7] * yi[2];
      y2 -= l[2] * yi[0] + l[5] * yi[1] + l[8] * yi[2];
    }
    y[3 * K] = y0, y[3 * K + 1] = y1, y[3 * K + 2] = y2;
  }
  x.resize(3 * nodes_);
  for (std::size_t o = 0; o < n; ++o)
    for (int a = 0; a < 3; ++a) x[static_cast<Eigen::Index>(3 * o) + a] = y[3 * perm_[o] + a];
}

}  // namespace gen4d::diagnose
