//! The hot loops of the diagnose forward model, the internal forces (Saint Venant-Kirchhoff,
//! Neo-Hookean and corotated laws) and element tangents (the first two) of the voxels, with the
//! 8 Gauss points of a voxel as the lanes of one vector.
//!
//! Each lane does the scalar element's arithmetic operation for operation, in the same order
//! (F = sum_l x_l (x) grad N_l, the law, the viscous parts, the region factor, the scatter),
//! and the 8 Gauss points' contributions to a node are summed in Gauss-point order, as the
//! scalar loop does. The file is compiled without floating-point contraction, so the result
//! is bit for bit the scalar loop's on every instruction set: the kernels are built for
//! AVX-512, AVX2 and the x86-64 baseline (SSE2), and one the CPU has is used.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <string>
#include <vector>

#include "materials/J2Return.hpp"

namespace gen4d::forward {

//! Shape functions of the element: the 8 trilinear corners, then the 3 incompatible (bubble)
//! modes of Wilson and Taylor, one per axis (see Model.cpp).
constexpr int kShapes = 11;

//! The principal stretch below which the forward model continues StVK's stress linearly
//! (materials::StVK::pk1_continued), in both element loops, scalar and vector: just above
//! StVK's limit point in uniaxial compression (1/sqrt 3 = 0.577), where its compressive stress
//! peaks and the law begins to soften, so StVK is unchanged wherever it is still stable that
//! way. A root of soft voxels under a clamped plate's in-plane bending otherwise let one Gauss
//! point of an incompatible-mode voxel snap to StVK's zero-energy reflection (volume ratio -1.1)
//! and the run fail a few steps later.
constexpr double kStvkContinuedStretch = 0.6;

using materials::mises;

//! The elastic laws the force pass has in lanes, each the arithmetic of its materials::
//! pk1, operation for operation (corotated: with the rotation of
//! materials::polar_rotation_newton, the signed SVD's where that declines, as the scalar
//! element loop takes it).
enum class ElasticLaw { StVK, NeoHookean, Corotated, Linear };

//! One internal-force pass over the voxels (an elastic law; optional one-term Prony
//! relaxation and Kelvin-Voigt stiffness damping: of the Green strain rate, carried by F, or
//! under the linear law of sym(dF/dt), as the scalar element loop takes them).
struct ElasticForcePass {
  ElasticLaw law = ElasticLaw::StVK;
  std::size_t voxels = 0;
  const std::array<int, 8>* vox_node = nullptr;  //!< corner nodes per voxel
  const std::array<double, 3>* X = nullptr;      //!< rest positions per node
  const double* u = nullptr;                     //!< displacements, 3 per node
  const double* v = nullptr;                     //!< velocities (Kelvin-Voigt only)
  const double* alpha = nullptr;       //!< bubble amplitudes, 9 per voxel (null: trilinear element)
  const double* alpha_rate = nullptr;  //!< their rates (Kelvin-Voigt only)
  const double* vfac = nullptr;        //!< stiffness factor per voxel
  //! Shape-function gradients (1/m) by shape, axis and Gauss point (zero for the bubbles of
  //! the trilinear element).
  const double (*G)[3][8] = nullptr;
  double weight = 0;          //!< a Gauss point's volume, h^3 / 8
  double mu = 0, lambda = 0;  //!< the law's Lame parameters
  //! Kelvin-Voigt: beta (0: none) with the Lame parameters its viscous stress uses.
  double kv_beta = 0, kv_mu = 0, kv_lambda = 0;
  //! Prony relaxation: q_new = (q + rate_g P) / (1 + rate) per Gauss point (9 each); null
  //! when off.
  const double* q = nullptr;
  double* q_new = nullptr;
  double prony_rate = 0, prony_rate_g = 0;
  double* max_mises = nullptr;  //!< when set: raised to the largest von Mises stress
  //! StVK, when set: counts the Gauss points whose stress was continued (or inverted).
  long* continued = nullptr;
  double* fint = nullptr;  //!< out: 3 per node (zeroed by the caller)
  double* ral = nullptr;   //!< out: the bubbles' residual, 9 per voxel
};

//! Runs the pass (with the instruction set in use).
void elastic_force_pass(const ElasticForcePass& p);

//! The element tangent of one voxel under StVK or Neo-Hookean (elastic): dP/dF by central
//! differences of the stress at the 8 Gauss points as lanes, then Ke = w sum_q B_q^T sym(D_q) B_q
//! over the first `shapes` shape functions, as the scalar element loop computes it.
struct ElasticTangent {
  ElasticLaw law = ElasticLaw::StVK;  //!< StVK or Neo-Hookean (the laws without an analytic dP/dF)
  const double (*G)[3][8] = nullptr;  //!< gradients (1/m) by shape, axis, Gauss point
  const double (*dN)[kShapes][3] = nullptr;  //!< unit-cube gradients by Gauss point [8]
  double mu = 0, lambda = 0;
  double eps = 1e-6;  //!< the central difference's step in F
  int shapes = kShapes;
};
//! x: the element's current positions (and bubble amplitudes); w: h/8 times the voxel's
//! factors; Ke: out, the 3 kShapes square matrix, column-major.
void elastic_element_tangent(const ElasticTangent& t, const double x[kShapes][3], double w,
                             double* Ke);

//! The incompatible element's condensed bubbles, per voxel and Newton iteration: with the
//! bubble block's inverse Kinv (9x9) and L = Kinv K_ab (9x24), both column-major,
//! out (24) = L^T r given Lt, L's transpose (24x9, column-major);
//! out (9) = s L x; out (9) = s Kinv x.
//! Each output sums its terms in the order of Eigen's SSE2 matrix-vector kernels (two
//! interleaved partial sums, even and odd terms, for L^T r; one running sum otherwise), so the
//! results are those of Eigen's products in the default build, bit for bit.
void bubble_lt_times(const double* Lt, const double* r, double* out);
void bubble_l_times(const double* L, const double* x, double s, double* out);
void bubble_kinv_times(const double* Kinv, const double* x, double s, double* out);

//! The instruction sets the kernels are built for that this CPU runs ("baseline", "avx2",
//! "avx512f"), the one in use (AVX2 where the CPU has it, the fastest measured, unless set),
//! and a switch for tests and benchmarks
//! (std::invalid_argument for one this CPU or build lacks; not thread-safe).
std::vector<std::string> element_kernel_isas();
std::string element_kernel_isa();
void set_element_kernel_isa(const std::string& isa);

}  // namespace gen4d::forward
