//! y = M x for a sparse matrix of the form m (x) I3 over nodes (3 dofs per node, numbered
//! consecutively; the same value on the three axes of a node pair, nothing across axes), as
//! the forward model's consistent mass is: one index per node pair instead of one per entry.
//! Every entry of y gets the terms of Eigen's column-major sparse-times-dense product in their
//! order (columns ascending, from zero), so the result is that product's bit for bit.
#pragma once

#include <Eigen/Sparse>
#include <vector>

namespace gen4d::forward {

class NodeBlockProduct {
 public:
  NodeBlockProduct() = default;
  //! From M (column-major); ok() is false when M is not of the form m (x) I3.
  explicit NodeBlockProduct(const Eigen::SparseMatrix<double>& M) {
    if (M.rows() != M.cols() || M.rows() % 3 != 0) return;
    const Eigen::Index n = M.rows() / 3;
    std::vector<std::vector<std::pair<int, double>>> rows(static_cast<std::size_t>(n));
    for (Eigen::Index B = 0; B < n; ++B) {
      Eigen::SparseMatrix<double>::InnerIterator c0(M, 3 * B), c1(M, 3 * B + 1), c2(M, 3 * B + 2);
      for (; c0; ++c0, ++c1, ++c2) {
        if (!c1 || !c2 || c0.row() % 3 != 0 || c1.row() != c0.row() + 1 ||
            c2.row() != c0.row() + 2 || c1.value() != c0.value() || c2.value() != c0.value())
          return;
        rows[static_cast<std::size_t>(c0.row() / 3)].emplace_back(static_cast<int>(B), c0.value());
      }
      if (c1 || c2) return;
    }
    start_.push_back(0);
    for (const auto& r : rows) {
      for (const auto& [B, v] : r) col_.push_back(B), val_.push_back(v);
      start_.push_back(static_cast<int>(col_.size()));
    }
  }
  bool ok() const { return !start_.empty(); }
  void apply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const {
    const double* xs = x.data();
    double* ys = y.data();
    const int n = static_cast<int>(start_.size()) - 1;
    for (int A = 0; A < n; ++A) {
      double s0 = 0, s1 = 0, s2 = 0;
      for (int k = start_[static_cast<std::size_t>(A)]; k < start_[static_cast<std::size_t>(A) + 1];
           ++k) {
        const double v = val_[static_cast<std::size_t>(k)];
        const double* xb = xs + 3 * col_[static_cast<std::size_t>(k)];
        s0 += v * xb[0];
        s1 += v * xb[1];
        s2 += v * xb[2];
      }
      ys[3 * A] = s0, ys[3 * A + 1] = s1, ys[3 * A + 2] = s2;
    }
  }

 private:
  std::vector<int> start_, col_;  //!< per node row: its node columns, ascending
  std::vector<double> val_;
};

}  // namespace gen4d::forward
