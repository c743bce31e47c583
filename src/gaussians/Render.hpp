//! CPU tile-based EWA splatting, matching the 3DGS rasterizer (graphdeco-inria
//! diff-gaussian-rasterization, forward pass) so that users see what they trained.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "gaussians/Camera.hpp"
#include "gaussians/Splats.hpp"
#include "parallel/Comm.hpp"

namespace gen4d::gaussians {

//! Wall-clock seconds of a render's phases and its sizes (filled when RenderOptions::stats is
//! set; a distributed render reports this rank's share).
struct RenderStats {
  double preprocess = 0;  //!< projection, covariance, colour per splat
  double exchange =
      0;              //!< distributed: sending projected splats to the ranks whose tiles they touch
  double sort = 0;    //!< depth order and binning into tiles
  double blend = 0;   //!< per-pixel compositing
  double gather = 0;  //!< distributed: collecting the tiles on rank 0
  double transfer = 0;           //!< GPU: copying the splats to the device and the image back
  std::size_t visible = 0;       //!< splats that survive culling (this rank's, before exchange)
  std::size_t tile_entries = 0;  //!< (splat, tile) pairs blended by this rank
};

struct RenderOptions {
  std::array<float, 3> background{0, 0, 0};  //!< colour channels in [0, 1]
  //! Host threads of the render (the image does not depend on it). 0: the OpenMP setting
  //! (OMP_NUM_THREADS; the drivers share the node's cores among its ranks).
  int threads = 0;
  //! Render on this rank's GPU where there is one (exec::use_device()). The GPU image equals
  //! the host's up to float rounding (fused multiply-adds, the device's exp); it is the same
  //! for every rank count and distribution of the splats.
  bool device = true;
  //! The host renderer's previous sort and blend (each pixel walking its tile's whole list, a
  //! comparison sort), kept as the benchmarks' baseline: the same image bit for bit.
  bool legacy = false;
  RenderStats* stats = nullptr;  //!< when set, receives the phase times
};

//! A float RGB image, rows top to bottom, 3 values per pixel.
struct Image {
  int width = 0, height = 0;
  std::vector<float> rgb;
};

//! Renders `splats` on this process alone (tile-based, 16x16 tiles), following forward.cu:
//! cull view depth <= 0.2; 2D covariance J W Sigma W^T J^T (t.x/t.z, t.y/t.z clamped to
//! 1.3 tan(fov/2)) + 0.3 I; radius ceil(3 sqrt(lambda_max)); a splat is drawn in the tiles its
//! square of that radius touches, front to back by view depth; alpha = min(0.99, o exp(power)),
//! skipped below 1/255, stopping before transmittance falls below 1e-4; output C + T bg.
//! Splats of equal depth are ordered by their projected data (bitwise), so the image does not
//! depend on the order in which the splats are listed.
Image render(const SplatFrame& splats, const Camera& camera, const RenderOptions& options = {});

//! Reference evaluator: every pixel walks every splat in the global depth order and blends
//! those whose screen rectangle covers the pixel's tile (the rasterizer's radius cut), with the
//! same rules, without tile lists (slow; for tests). Equal to render() bit for bit.
Image render_brute_force(const SplatFrame& splats, const Camera& camera,
                         const RenderOptions& options = {});

//! Collective render: each rank passes its own splats (any distribution; the union is drawn);
//! the image is identical for every distribution and rank count and is returned on rank 0
//! (empty elsewhere).
Image render_distributed(MPI_Comm comm, const SplatFrame& local, const Camera& camera,
                         const RenderOptions& options = {});

//! An orbit camera (azimuth 45, elevation 20 degrees about `up`) that frames the splats: it
//! looks at the centre of the box spanned by the 2nd to 98th percentile of their positions per
//! axis (stray splats do not zoom it out) from where the box's bounding sphere fills the
//! narrower field of view. InputError when there are no splats.
OrbitCamera framing_orbit(const SplatFrame& splats, int width, int height, double fov_y_degrees,
                          const std::array<double, 3>& up = {0, 0, 1});
//! The same for the box [lo, hi].
OrbitCamera framing_orbit(const std::array<double, 3>& lo, const std::array<double, 3>& hi,
                          int width, int height, double fov_y_degrees,
                          const std::array<double, 3>& up = {0, 0, 1});
//! The box of the 2nd to 98th percentiles of the splats' positions along each axis (InputError
//! when there are none): {lo, hi}.
std::array<std::array<double, 3>, 2> central_box(const SplatFrame& splats);

//! 8-bit PNG of an image (clamped to [0, 1], rounded), through a temporary and a rename.
void write_image_png(const std::string& path, const Image& image);

//! Peak signal-to-noise ratio in dB between two images of the same size (peak 1).
double psnr(const Image& a, const Image& b);

}  // namespace gen4d::gaussians
