#include "diagnose/BlockLDLT.hpp"

#include <Eigen/OrderingMethods>
#include <stdexcept>

namespace gen4d::diagnose {

namespace {

using Perm = Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int>;

BlockLDLT::SpMat permuted(const BlockLDLT::SpMat& A, const Perm& p) {
  BlockLDLT::SpMat Ap;
  Ap = A.twistedBy(p);
  return Ap;
}

}  // namespace

void BlockLDLT::analyze(const SpMat& A) {
  if (A.rows() != A.cols() || A.rows() % 3 != 0)
    throw std::logic_error("BlockLDLT: the matrix must be square with 3 dofs per node");
  nodes_ = static_cast<int>(A.rows() / 3);
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(static_cast<std::size_t>(A.nonZeros() + nodes_));
  for (int k = 0; k < A.outerSize(); ++k)
    for (SpMat::InnerIterator it(A, k); it; ++it)
      t.emplace_back(static_cast<int>(it.row() / 3), static_cast<int>(it.col() / 3), 1.0);
  for (int i = 0; i < nodes_; ++i) t.emplace_back(i, i, 1.0);
  SpMat G(nodes_, nodes_);
  G.setFromTriplets(t.begin(), t.end());
  Perm node_pinv;
  Eigen::AMDOrdering<int> amd;
  amd(G, node_pinv);
  const Perm node_p = node_pinv.inverse();  // new node index of each old node
  perm_.resize(3 * nodes_);
  for (int i = 0; i < nodes_; ++i)
    for (int a = 0; a < 3; ++a) perm_.indices()[3 * i + a] = 3 * node_p.indices()[i] + a;
  ldlt_.analyzePattern(permuted(A, perm_));
  y_.resize(3 * nodes_);
}

bool BlockLDLT::factorize(const SpMat& A) {
  ldlt_.factorize(permuted(A, perm_));
  if (ldlt_.info() != Eigen::Success) return false;
  // Copy L (unit lower, diagonal not stored) into 3x3 blocks: a node's three columns share
  // one row pattern below their diagonal block.
  const SpMat& L = ldlt_.matrixL().nestedExpression();
  const Eigen::VectorXd& D = ldlt_.vectorD();
  diag_.assign(6 * static_cast<std::size_t>(nodes_), 0.0);
  start_.assign(static_cast<std::size_t>(nodes_) + 1, 0);
  row_.clear();
  val_.clear();
  std::vector<int> slot(static_cast<std::size_t>(nodes_), -1);
  for (int K = 0; K < nodes_; ++K) {
    start_[static_cast<std::size_t>(K)] = static_cast<int>(row_.size());
    for (int b = 0; b < 3; ++b) {
      const int col = 3 * K + b;
      for (SpMat::InnerIterator it(L, col); it; ++it) {
        const int r = static_cast<int>(it.row());
        if (r <= col) continue;
        const int I = r / 3, a = r % 3;
        if (I == K) {  // (a, b) = (1, 0), (2, 0) or (2, 1)
          diag_[6 * static_cast<std::size_t>(K) + static_cast<std::size_t>(a + b - 1)] = it.value();
          continue;
        }
        int& s = slot[static_cast<std::size_t>(I)];
        if (s < 0) {
          s = static_cast<int>(row_.size());
          row_.push_back(I);
          val_.resize(val_.size() + 9, 0.0);
        }
        val_[9 * static_cast<std::size_t>(s) + static_cast<std::size_t>(3 * a + b)] = it.value();
      }
      diag_[6 * static_cast<std::size_t>(K) + 3 + static_cast<std::size_t>(b)] = D[col];
    }
    for (std::size_t j = static_cast<std::size_t>(start_[static_cast<std::size_t>(K)]);
         j < row_.size(); ++j)
      slot[static_cast<std::size_t>(row_[j])] = -1;
  }
  start_[static_cast<std::size_t>(nodes_)] = static_cast<int>(row_.size());
  return true;
}

void BlockLDLT::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) const {
  double* y = y_.data();
  const int* p = perm_.indices().data();
  for (int i = 0; i < 3 * nodes_; ++i) y[p[i]] = b[i];
  const double* dg = diag_.data();
  const int* st = start_.data();
  const int* rw = row_.data();
  const double* v = val_.data();
  // L y = b
  for (int K = 0; K < nodes_; ++K) {
    double* yk = y + 3 * K;
    const double* d = dg + 6 * K;
    yk[1] -= d[0] * yk[0];
    yk[2] -= d[1] * yk[0] + d[2] * yk[1];
    const double y0 = yk[0], y1 = yk[1], y2 = yk[2];
    for (int j = st[K]; j < st[K + 1]; ++j) {
      double* yi = y + 3 * rw[j];
      const double* l = v + 9 * j;
      yi[0] -= l[0] * y0 + l[1] * y1 + l[2] * y2;
      yi[1] -= l[3] * y0 + l[4] * y1 + l[5] * y2;
      yi[2] -= l[6] * y0 + l[7] * y1 + l[8] * y2;
    }
  }
  // D
  for (int K = 0; K < nodes_; ++K)
    for (int a = 0; a < 3; ++a) y[3 * K + a] /= dg[6 * K + 3 + a];
  // L^T x = y
  for (int K = nodes_ - 1; K >= 0; --K) {
    double y0 = y[3 * K], y1 = y[3 * K + 1], y2 = y[3 * K + 2];
    for (int j = st[K]; j < st[K + 1]; ++j) {
      const double* yi = y + 3 * rw[j];
      const double* l = v + 9 * j;
      y0 -= l[0] * yi[0] + l[3] * yi[1] + l[6] * yi[2];
      y1 -= l[1] * yi[0] + l[4] * yi[1] + l[7] * yi[2];
      y2 -= l[2] * yi[0] + l[5] * yi[1] + l[8] * yi[2];
    }
    const double* d = dg + 6 * K;
    y1 -= d[2] * y2;
    y0 -= d[0] * y1 + d[1] * y2;
    y[3 * K] = y0, y[3 * K + 1] = y1, y[3 * K + 2] = y2;
  }
  x.resize(3 * nodes_);
  for (int i = 0; i < 3 * nodes_; ++i) x[i] = y[p[i]];
}

}  // namespace gen4d::diagnose
