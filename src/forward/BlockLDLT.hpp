//! Sparse block LDL^T of a symmetric matrix made of 3x3 node blocks (3 dofs per node, numbered
//! consecutively): A = L D L^T with L unit block-lower-triangular and D block-diagonal (3x3).
//!
//! The nodes are ordered by AMD on the node graph (Eigen's AMDOrdering); the block structure
//! of L comes from a symbolic elimination on that graph (once per pattern), and the numeric
//! factorization is left-looking over 3x3 blocks, so both the factorization and the solves
//! read one index per 9 values. In the diagnose forward model a run factors the step matrix
//! tens of times and solves with it thousands of times; both were a third of a run with a
//! scalar simplicial LDL^T. No pivoting: A must have nonsingular leading block minors (true
//! for the model's SPD step matrices; an indefinite but nonsingular one also factors).
//!
//! The block products run as 4-lane vectors, one lane per row or column of a block (the 4th
//! lane is padding), each lane doing the scalar block product's arithmetic in its order, so
//! every instruction set's build gives the same bits (Isa.hpp); AVX2 where the CPU has it.
//! The baseline build's substitutions are scalar loops with the same sums.
#pragma once

#include <Eigen/Sparse>
#include <string>
#include <vector>

namespace gen4d::forward {

class BlockLDLT {
 public:
  using SpMat = Eigen::SparseMatrix<double>;

  //! Ordering and block structure of L from the pattern of A (both triangles stored, 3 dofs
  //! per node); std::logic_error when A is not square with 3 dofs per node.
  void analyze(const SpMat& A);
  //! Numeric factorization of A, whose pattern must lie within analyze()'s. False when a
  //! diagonal block pivot is singular or not finite.
  bool factorize(const SpMat& A);
  //! x = A^-1 b with the last factorization; x and b may not alias.
  void solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) const;
  //! Nonzero 3x3 blocks of L below its diagonal.
  std::size_t off_blocks() const { return row_.size(); }

  //! The instruction sets the block kernels are built for that this CPU runs ("baseline",
  //! "avx2"), the one in use, and a switch for tests and benchmarks (std::invalid_argument
  //! for one this CPU or build lacks; not thread-safe).
  static std::vector<std::string> isas();
  static std::string isa();
  static void set_isa(const std::string& isa);

 private:
  int nodes_ = 0;
  std::vector<int> perm_;   //!< new node index of each old node
  std::vector<int> iperm_;  //!< old node of each new index
  std::vector<int> start_;  //!< per node column K: its blocks are [start_[K], start_[K+1])
  std::vector<int> row_;    //!< row node of each block (ascending within a column)
  //! Per node K: (J, block index of L_KJ) for every column J < K with a block in row K.
  std::vector<std::vector<std::pair<int, int>>> row_blocks_;
  // Blocks are stored as 3 rows of 4 (the last one 0): 12 values per block.
  std::vector<double> L_;          //!< L per block, row-major
  std::vector<double> LT_;         //!< L^T per block (the forward substitution reads columns)
  std::vector<double> MT_;         //!< (L_IK D_K)^T per block (the left-looking updates use it)
  std::vector<double> Dinv_;       //!< 9 values per node: D_K^-1, row-major
  std::vector<double> W_;          //!< work: 12 per block of the current column, + 12 for D_K
  std::vector<int> slot_;          //!< work: row node -> position in the current column
  mutable std::vector<double> y_;  //!< permuted work vector, 4 values per node
};

}  // namespace gen4d::forward
