//! Conversions between gen4d's row-major Mat3 and Eigen, for tests that check against Eigen.
#pragma once

#include <Eigen/Dense>

#include "materials/Mat3.hpp"

namespace gen4d::test {

inline Eigen::Matrix3d to_eigen(const materials::Mat3& A) {
  return Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(A.a);
}

inline materials::Mat3 from_eigen(const Eigen::Matrix3d& A) {
  materials::Mat3 M;
  Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(M.a) = A;
  return M;
}

}  // namespace gen4d::test
