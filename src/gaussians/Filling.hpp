//! Internal filling of a trained splat object (PhysGaussian seed §3.7; its code's
//! `particle_filling/filling.py`): an opacity density field on a grid, particles in its dense
//! ("surface") cells and in the empty cells the surface encloses, each new particle an isotropic
//! Gaussian that takes opacity and colour from its nearest original Gaussian.
//
// Directions are numbered as PhysGaussian numbers them: 0 +x, 1 -x, 2 +y, 3 -y, 4 +z, 5 -z;
// -1 means none.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "gaussians/Splats.hpp"

namespace gen4d::gaussians {

//! Options of fill_interior. Defaults are PhysGaussian's (`utils/decode_param.py`,
//! `particle_filling`), except where noted.
struct FillingOptions {
  //! Cells along the longest edge of the box; the cells are cubes of edge dx = longest edge /
  //! n_grid (PhysGaussian: 4 x its MPM grid's default 50).
  int n_grid = 200;
  //! A cell whose density exceeds this is a surface cell; it is topped up to
  //! max_particles_per_cell particles (counting the original Gaussians centred in it).
  double density_threshold = 5.0;
  //! Density above which a cell stops a ray (the six-ray test and the crossing count).
  double search_threshold = 3.0;
  //! Particles placed in each filled cell (PhysGaussian's `max_partciels_per_cell`).
  int max_particles_per_cell = 1;
  //! The one of the six rays that need not hit the surface (an object standing open on the
  //! ground: -z); -1: all six must hit.
  int search_exclude_direction = 5;
  //! The ray whose surface crossings (rises of the density above search_threshold) must be odd;
  //! -1: no parity test.
  int ray_cast_direction = 4;
  //! Cap on the new particles (PhysGaussian's `max_particles_num`); more is an InputError.
  std::size_t max_particles = 2000000;
  //! Give the grid's box explicitly (PhysGaussian's `boundary`; only Gaussians centred strictly
  //! inside it add density). Otherwise the box is the bounds of the Gaussians' centres, widened
  //! by box_padding_cells cells on every side so the surface never touches the grid's edge.
  bool has_box = false;
  std::array<double, 3> box_lo{0, 0, 0};
  std::array<double, 3> box_hi{0, 0, 0};
  int box_padding_cells = 2;
  //! A Gaussian adds density to the cells within support_sigmas standard deviations of its mean
  //! along its widest axis (PhysGaussian: 1, rounded up to whole cells), at most
  //! max_support_cells cells either side of its own cell (PhysGaussian: unbounded, so a huge
  //! Gaussian can take days); such a Gaussian is counted as clamped.
  double support_sigmas = 3.0;
  int max_support_cells = 8;
  //! Place surface cells' particles (PhysGaussian's `fill_dense_grids`); false: interior only.
  bool fill_surface_cells = true;
  //! Seed of the particles' positions in their cells (a hash of seed, cell and particle: the
  //! output does not depend on thread count or order).
  std::uint64_t seed = 0;
  //! Seconds between progress lines (log::info) of a long filling.
  double progress_interval = 5.0;
};

//! A grid cell's state after filling.
enum class FillCell : std::uint8_t {
  empty = 0,     //!< no Gaussian centre, not dense, not enclosed
  occupied = 1,  //!< an original Gaussian's centre lies in it (never filled as interior)
  surface = 2,   //!< density above density_threshold
  interior = 3,  //!< empty and enclosed: filled
};

//! The new particles and what filling found.
struct FillingResult {
  //! The new particles only (surface cells' first, then interior cells', each in cell order
  //! x fastest): isotropic scale r = (3 V / (4 pi))^(1/3) with V = dx^3 / max_particles_per_cell,
  //! identity rotation, opacity and SH of the nearest original Gaussian (same sh_degree).
  SplatSet particles;

  std::array<int, 3> dims{0, 0, 0};       //!< cells per axis
  std::array<double, 3> origin{0, 0, 0};  //!< the box's low corner
  double dx = 0;                          //!< cell edge
  std::vector<FillCell> cells;            //!< dims product, x fastest
  std::vector<double> density;            //!< the opacity density field, same layout
  double particle_volume = 0;             //!< V above
  double particle_radius = 0;             //!< r above

  std::size_t surface_cells = 0;       //!< cells above density_threshold
  std::size_t surface_particles = 0;   //!< particles placed in them
  std::size_t interior_cells = 0;      //!< enclosed empty cells
  std::size_t interior_particles = 0;  //!< particles placed in them
  std::size_t splats_in_box = 0;       //!< Gaussians that added density
  //! Gaussians whose covariance is singular (smallest eigenvalue <= 1e-12 x the largest, e.g.
  //! a zero scale); their eigenvalues are raised to (0.01 dx)^2 as PhysGaussian raises them.
  std::size_t degenerate_splats = 0;
  std::size_t clamped_splats = 0;  //!< Gaussians whose support was cut to max_support_cells

  double seconds_density = 0;     //!< density field
  double seconds_cells = 0;       //!< surface cells, ray tests, particle positions
  double seconds_attributes = 0;  //!< nearest original Gaussian of every new particle
  double seconds_total = 0;

  std::size_t cell_index(int i, int j, int k) const {
    return (static_cast<std::size_t>(k) * dims[1] + j) * dims[0] + i;
  }
};

//! Fills the inside of `splats` with particles (see FillingOptions). InputError on an option out
//! of range, a non-finite splat value, an empty set or a box of no volume, or more particles
//! than max_particles. Runs in time linear in splats x (2 max_support_cells + 2)^3 + cells +
//! new particles x log(splats); serial and deterministic.
FillingResult fill_interior(const SplatSet& splats, const FillingOptions& options);

}  // namespace gen4d::gaussians
