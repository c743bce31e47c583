//! Gaussian kinematics under a deformation map (seed §3.4-3.5): the deformed covariance
//! a = F A0 F^T and the harmonics evaluated at R^T d, R the rotation of F's polar decomposition.
#pragma once

#include <array>
#include <cstddef>
#include <string>

#include "gaussians/Splats.hpp"

namespace gen4d::gaussians {

//! How covariance and harmonics follow the deformation. Full is the method; the other three are
//! the seed's ablations (Table 1).
struct KinematicsOptions {
  enum class Covariance {
    Deformed,  //!< a = F A0 F^T (full method)
    Fixed,     //!< a = A0 (ablation "fixed covariance")
    Rigid      //!< a = R A0 R^T (ablation "rigid covariance")
  };
  Covariance covariance = Covariance::Deformed;
  bool rotate_harmonics = true;  //!< false: ablation "fixed harmonics" (SH at d, not R^T d)
  //! Parses "full" | "fixed_covariance" | "rigid_covariance" | "fixed_harmonics"; InputError
  //! naming `where` otherwise.
  static KinematicsOptions parse(const std::string& name, const std::string& where);
};

//! Rotation of the signed polar decomposition F = R S (det R = +1 even when det F < 0, and
//! well defined for degenerate F), row-major 3x3 in and out. RuntimeError for a non-finite F.
std::array<double, 9> polar_rotation(const std::array<double, 9>& F);

//! a = F A F^T for a symmetric A (6 values) and row-major F.
std::array<double, 6> transform_covariance(const std::array<double, 9>& F,
                                           const std::array<double, 6>& A);

//! Rate form of the covariance update (PhysGaussian's default `update_cov`): a <- a + dt (L a +
//! a L^T) with L the velocity gradient (row-major), in place.
void rate_update_covariance(const std::array<double, 9>& L, double dt, std::array<double, 6>& a);

//! Splat i of `rest` moved to `x` (3) with deformation gradient `F` (row-major), appended to
//! `out` (whose sh_degree must equal rest's, and whose sh_rotation holds 9 per splat when
//! opt.rotate_harmonics, none otherwise; std::logic_error else). Covariance and harmonics per
//! `opt`; when `covariance_override` (6 values) is non-null it replaces F A0 F^T under
//! Covariance::Deformed (the rate form); the Fixed and Rigid ablations ignore it.
void append_deformed(const SplatSet& rest, std::size_t i, const double* x, const double* F,
                     const KinematicsOptions& opt, SplatFrame& out,
                     const double* covariance_override = nullptr);

//! The undeformed splats (F = I everywhere, so sh_rotation is left empty), for rendering a rest
//! state.
SplatFrame rest_frame(const SplatSet& rest);

}  // namespace gen4d::gaussians
