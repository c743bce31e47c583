//! Internals shared by the serial and distributed renderers (not part of the public API).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "gaussians/Camera.hpp"
#include "gaussians/Render.hpp"
#include "gaussians/Splats.hpp"

namespace gen4d::gaussians::detail {

inline constexpr int kTile = 16;

//! A visible splat after preprocessing: screen position, conic, opacity, colour, view depth,
//! and the tile rectangle [x0, x1) x [y0, y1) it is drawn in. Trivially copyable (sent as bytes).
struct Projected {
  float x, y;
  float conic[3];
  float opacity;
  float rgb[3];
  float depth;
  float radius;
  std::uint16_t x0, y0, x1, y1;
};

//! Per-render camera quantities in single precision, as the rasterizer holds them.
struct View {
  int width = 0, height = 0, grid_x = 0, grid_y = 0;
  float view[9];   //!< world -> camera rotation, row-major (R^T)
  float trans[3];  //!< world -> camera translation (-R^T position)
  float campos[3];
  float fx, fy, tan_fovx, tan_fovy, cx, cy;
  explicit View(const Camera& camera);
};

//! Appends the visible splats of `splats` (culling as forward.cu's preprocessCUDA) to `out`.
void preprocess(const SplatFrame& splats, const View& view, std::vector<Projected>& out,
                int threads);

//! The canonical front-to-back order: view depth, then the projected data bitwise.
bool before(const Projected& a, const Projected& b);

//! Sorts `splats` canonically and bins them into tile rows [row0, row1): `offsets` (one per
//! tile of those rows, plus one) index `entries`, which lists each tile's splats front to back.
void bin_tiles(std::vector<Projected>& splats, const View& view, int row0, int row1,
               std::vector<std::uint32_t>& offsets, std::vector<std::uint32_t>& entries);

//! Blends the tiles of rows [row0, row1) into `rgb` (rows row0 * 16 .. of the image, 3 floats
//! per pixel), using `threads` threads.
void blend_tiles(const std::vector<Projected>& splats, const View& view, int row0, int row1,
                 const std::vector<std::uint32_t>& offsets,
                 const std::vector<std::uint32_t>& entries, const RenderOptions& options,
                 float* rgb, int threads);

//! The number of threads for `options` (at least 1), dividing the hardware threads by
//! `sharing` processes when options.threads is 0.
int thread_count(const RenderOptions& options, int sharing);

}  // namespace gen4d::gaussians::detail
