//! 3D Gaussian splats carried by MPM particles (PhysGaussian seed §3.3-3.4): each particle holds
//! its splat's rest shape, the total deformation gradient, the rate-form covariance, opacity
//! and harmonics in Particles::extra, so they migrate, checkpoint and restart with it.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "gaussians/Kinematics.hpp"
#include "gaussians/Splats.hpp"
#include "mpm/Particles.hpp"
#include "parallel/Comm.hpp"

namespace gen4d::mpm {

//! Where the splat attributes sit in a particle's extra values.
struct SplatLayout {
  static constexpr int kScale = 0;        //!< 3: rest standard deviations along the local axes
  static constexpr int kRotation = 3;     //!< 4: rest orientation, unit quaternion w, x, y, z
  static constexpr int kF = 7;            //!< 9: total deformation gradient, row-major
  static constexpr int kCovariance = 16;  //!< 6: covariance of the rate form (upper triangle)
  static constexpr int kOpacity = 22;     //!< 1
  static constexpr int kSh = 23;          //!< 3 K: harmonics, Splats.hpp's layout

  int sh_degree = 0;

  int width() const { return kSh + 3 * gaussians::sh_coefficients(sh_degree); }
  //! Names of the extra values (checkpoint attribute extra_names).
  std::vector<std::string> names() const;
  //! The layout whose names() are `names`; InputError naming `where` otherwise.
  static SplatLayout from_names(const std::vector<std::string>& names, const std::string& where);
};

//! How the covariance that is drawn follows the flow.
enum class CovarianceUpdate {
  DeformationGradient,  //!< a = F A0 F^T with the total deformation gradient
  Rate                  //!< a <- a + dt (L a + a L^T) every substep (PhysGaussian's default)
};
//! Parses "deformation_gradient" | "rate"; InputError naming `where` otherwise.
CovarianceUpdate parse_covariance_update(const std::string& name, const std::string& where);

//! Rest extra values of splat i of `splats` (its harmonics zero-padded to layout.sh_degree,
//! which must not be lower: std::logic_error), F = I, covariance A0, into out[0, width).
void splat_rest_values(const gaussians::SplatSet& splats, std::size_t i, const SplatLayout& layout,
                       double* out);

//! Rest extra values of an isotropic splat of standard deviation `sigma`, opacity `opacity` and
//! colour `rgb` (linear, [0, 1]: SH DC = (rgb - 0.5) / C0, higher coefficients zero).
void isotropic_rest_values(double sigma, double opacity, const double* rgb,
                           const SplatLayout& layout, double* out);

//! Kinematics of one substep, after Solver::substep (p.C is then the velocity gradient of the
//! G2P transfer, as the solver's F update uses it): F_tot <- (I + dt C) F_tot, and in Rate mode
//! the covariance's rate update, for every particle not frozen (flag bit 0).
void advance_splats(Particles& p, const SplatLayout& layout, double dt, CovarianceUpdate mode);

//! This rank's particles as rest splats (position the current one), in particle order.
gaussians::SplatSet rest_splats(const Particles& p, const SplatLayout& layout);

//! This rank's particles as deformed splats to render (gaussians::append_deformed with F_tot,
//! or the rate covariance in Rate mode).
gaussians::SplatFrame splat_frame(const Particles& p, const SplatLayout& layout,
                                  const gaussians::KinematicsOptions& options,
                                  CovarianceUpdate mode);

//! Every particle's deformed splat, in id order, on rank 0 (empty elsewhere; collective): the
//! deformed covariance (as splat_frame's) as standard deviations and an orientation, the
//! harmonics rotated by the polar rotation of F_tot where options rotate them, ready for
//! gaussians::write_splats_ply.
gaussians::SplatSet gather_deformed_splats(MPI_Comm comm, const Particles& p,
                                           const SplatLayout& layout,
                                           const gaussians::KinematicsOptions& options,
                                           CovarianceUpdate mode);

}  // namespace gen4d::mpm
