#include "mpm/Seeding.hpp"

#include <algorithm>
#include <cmath>

namespace gen4d::mpm {

Particles seed_particles(MPI_Comm comm, const GridSpec& grid, const geometry::Shape& shape, int ppa,
                         const Material& material, const Vec3d& velocity) {
  int rank = 0, size = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &size);
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
  std::int64_t offset = 0;
  MPI_Exscan(&count, &offset, 1, MPI_INT64_T, MPI_SUM, comm);
  if (rank == 0) offset = 0;
  for (auto& id : p.id) id += offset;
  return p;
}

}  // namespace gen4d::mpm
