//! 3D Gaussian splats (Kerbl et al. 2023): a trained object's Gaussians in activated form, and
//! the deformed splats a renderer draws (PhysGaussian seed §3.4-3.5).
//
// Conventions shared by every file of src/gaussians:
// - Spherical harmonics: K = (degree + 1)^2 coefficients per colour channel, stored
//   coefficient-major: sh[(i * K + k) * 3 + c] is coefficient k of channel c (0 r, 1 g, 2 b) of
//   splat i; k = 0 is the DC term (the file's f_dc_c), k >= 1 the file's f_rest (which the PLY
//   stores channel-major: f_rest_{(k - 1) + c (K - 1)}).
// - Colour of a splat seen along unit direction d (from the camera centre to its mean):
//   max(SH(d) + 0.5, 0) per channel (3DGS's convention).
// - Covariances are symmetric 3x3 matrices stored as their upper triangle, 6 values per splat:
//   xx, xy, xz, yy, yz, zz.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace gen4d::gaussians {

inline constexpr int kMaxShDegree = 3;
//! Coefficients per channel at SH degree `degree` (0..3): 1, 4, 9, 16.
constexpr int sh_coefficients(int degree) {
  return (degree + 1) * (degree + 1);
}

//! A set of Gaussians in their rest (trained) state, values activated as 3DGS uses them.
struct SplatSet {
  int sh_degree = 0;             //!< 0..3
  std::vector<double> position;  //!< 3 per splat (world units of the capture or the deck)
  std::vector<double> scale;  //!< 3 per splat: standard deviations along the local axes (exp of the
                              //!< file's log-scale)
  std::vector<double> rotation;  //!< 4 per splat: unit quaternion w, x, y, z (local -> world)
  std::vector<double> opacity;   //!< 1 per splat, in (0, 1) (sigmoid of the file's logit)
  std::vector<double> sh;        //!< 3 K per splat, layout above

  std::size_t size() const { return opacity.size(); }
  int coefficients() const { return sh_coefficients(sh_degree); }
  //! Throws std::logic_error when the array lengths do not match size() and sh_degree.
  void check_sizes() const;
  //! Rest covariance R S S^T R^T of splat i (6 values, upper triangle).
  std::array<double, 6> covariance(std::size_t i) const;
};

//! Appends the splats of `from` to `to`, raising the SH degree of either to the larger one (the
//! added coefficients zero). `to` may be empty (sh_degree then taken from `from`).
void append_splats(SplatSet& to, const SplatSet& from);

//! What a renderer draws: deformed splats in world space, single precision as the 3DGS
//! rasterizer uses. Built from a SplatSet by the kinematics (gaussians/Kinematics.hpp).
struct SplatFrame {
  int sh_degree = 0;
  std::vector<float> position;    //!< 3 per splat
  std::vector<float> covariance;  //!< 6 per splat (upper triangle)
  std::vector<float> opacity;     //!< 1 per splat
  std::vector<float> sh;          //!< 3 K per splat
  //! Empty, or 9 per splat (row-major R): the colour is evaluated at R^T d instead of d (the
  //! harmonics rotated with the material, seed §3.5).
  std::vector<float> sh_rotation;

  std::size_t size() const { return opacity.size(); }
  int coefficients() const { return sh_coefficients(sh_degree); }
  //! Appends every splat of `other` (same sh_degree, which an empty frame takes from `other`;
  //! sh_rotation both present or both empty unless one frame is empty). std::logic_error
  //! otherwise.
  void append(const SplatFrame& other);
};

}  // namespace gen4d::gaussians
