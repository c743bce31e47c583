//! Sparse LDL^T of a symmetric matrix made of 3x3 node blocks (3 dofs per node, numbered
//! consecutively), with triangular solves on 3x3 blocks.
//!
//! The factorization is Eigen's SimplicialLDLT on the matrix permuted by an AMD ordering of
//! the node graph (so a node's three dofs stay adjacent and L is made of dense 3x3 blocks);
//! after each factorization L is copied into a block-compressed layout, whose solves read one
//! row index per 9 values instead of one per value. In the diagnose forward model a run does
//! thousands of solves per factorization, and the solve is its second-largest cost.
#pragma once

#include <Eigen/Sparse>
#include <vector>

namespace gen4d::diagnose {

class BlockLDLT {
 public:
  using SpMat = Eigen::SparseMatrix<double>;

  //! Symbolic analysis of the pattern of A (ndof = 3 * nodes, both triangles stored).
  void analyze(const SpMat& A);
  //! Numeric factorization of A (same pattern as analyze()'s, or a subset of it).
  bool factorize(const SpMat& A);
  //! x = A^-1 b with the last factorization; x and b may not alias.
  void solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) const;
  //! Nonzero 3x3 blocks of L below the diagonal blocks (for tests and benchmarks).
  std::size_t off_blocks() const { return row_.size(); }

 private:
  Eigen::SimplicialLDLT<SpMat, Eigen::Lower, Eigen::NaturalOrdering<int>> ldlt_;
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> perm_;  //!< new = perm(old)
  int nodes_ = 0;
  std::vector<double> diag_;   //!< per node: the strictly lower part of its diagonal block
                               //!< (l10, l20, l21) and D (d0, d1, d2)
  std::vector<int> start_;     //!< per node column: first off-diagonal block
  std::vector<int> row_;       //!< row node of each off-diagonal block
  std::vector<double> val_;    //!< 9 values per block, row-major (row dof a, column dof b)
  mutable Eigen::VectorXd y_;  //!< permuted work vector
};

}  // namespace gen4d::diagnose
