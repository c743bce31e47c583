#include "mpm/Seeding.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "mpm/SplatParticles.hpp"
#include "parallel/Comm.hpp"

namespace gen4d::mpm {

Particles seed_particles(MPI_Comm comm, const GridSpec& grid, const geometry::Shape& shape, int ppa,
                         const Material& material, const Vec3d& velocity) {
  const int rank = parallel::rank(comm), size = parallel::size(comm);
  const geometry::Aabb b = shape.bounds();
  long lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::max(0L, static_cast<long>(std::floor((b.lo[a] - grid.lo[a]) / grid.dx)));
    hi[a] = std::min(grid.cells[a], static_cast<long>(std::ceil((b.hi[a] - grid.lo[a]) / grid.dx)));
  }
  // This rank's slab of z-layers.
  const long nz = std::max(0L, hi[2] - lo[2]);
  const long k0 = lo[2] + nz * rank / size, k1 = lo[2] + nz * (rank + 1) / size;
  const double vol = grid.dx * grid.dx * grid.dx / (ppa * ppa * ppa);
  const double mass = material.density() * vol;
  double init[kStateSize];
  material.init_state(init);
  Particles p;
  std::vector<std::int64_t> local_ids;
  std::int64_t count = 0;
  for (long k = k0; k < k1; ++k)
    for (long j = lo[1]; j < hi[1]; ++j)
      for (long i = lo[0]; i < hi[0]; ++i)
        for (int c = 0; c < ppa; ++c)
          for (int bb = 0; bb < ppa; ++bb)
            for (int a = 0; a < ppa; ++a) {
              const double pos[3] = {grid.lo[0] + (i + (a + 0.5) / ppa) * grid.dx,
                                     grid.lo[1] + (j + (bb + 0.5) / ppa) * grid.dx,
                                     grid.lo[2] + (k + (c + 0.5) / ppa) * grid.dx};
              if (!shape.inside(Eigen::Vector3d(pos[0], pos[1], pos[2]))) continue;
              p.push_back(count++, pos, velocity.data(), mass, vol, init);
            }
  const std::int64_t offset = parallel::exclusive_prefix_sum(comm, count);
  for (auto& id : p.id) id += offset;
  return p;
}

Particles seed_splats(MPI_Comm comm, const GridSpec& grid, const gaussians::SplatSet& splats,
                      const Material& material, const Vec3d& velocity, std::int64_t first_id,
                      int sh_degree, const std::string& where) {
  const int rank = parallel::rank(comm), size = parallel::size(comm);
  splats.check_sizes();
  const std::size_t n = splats.size();
  // Splats per grid cell, over the whole set (every rank holds it).
  std::vector<std::int64_t> cell(n);
  std::string error;
  for (std::size_t i = 0; i < n && error.empty(); ++i) {
    long c[3] = {0, 0, 0};
    for (int a = 0; a < 3; ++a) {
      const double X = std::floor((splats.position[3 * i + a] - grid.lo[a]) / grid.dx);
      if (!(X >= 0 && X < static_cast<double>(grid.cells[a]))) {
        error = fmt::format("{}: splat {} at ({:.6g}, {:.6g}, {:.6g}) lies outside the MPM grid",
                            where, i, splats.position[3 * i], splats.position[3 * i + 1],
                            splats.position[3 * i + 2]);
        break;
      }
      c[a] = static_cast<long>(X);
    }
    cell[i] = (static_cast<std::int64_t>(c[2]) * grid.cells[1] + c[1]) * grid.cells[0] + c[0];
  }
  // Every rank checks the same set: the error is the same everywhere.
  if (!error.empty()) throw InputError(error);
  std::unordered_map<std::int64_t, int> per_cell;
  per_cell.reserve(n);
  for (std::int64_t c : cell) ++per_cell[c];
  const SplatLayout layout{std::max(splats.sh_degree, sh_degree)};
  const double cell_volume = grid.dx * grid.dx * grid.dx;
  double init[kStateSize];
  material.init_state(init);
  Particles p;
  p.extra_width = layout.width();
  const std::size_t i0 = n * static_cast<std::size_t>(rank) / static_cast<std::size_t>(size);
  const std::size_t i1 = n * static_cast<std::size_t>(rank + 1) / static_cast<std::size_t>(size);
  p.reserve(i1 - i0);
  std::vector<double> values(static_cast<std::size_t>(layout.width()));
  for (std::size_t i = i0; i < i1; ++i) {
    const double vol = cell_volume / per_cell[cell[i]];
    splat_rest_values(splats, i, layout, values.data());
    p.push_back(first_id + static_cast<std::int64_t>(i), &splats.position[3 * i], velocity.data(),
                material.density() * vol, vol, init, values.data());
  }
  return p;
}

}  // namespace gen4d::mpm
