#include "mpm/PointMass.hpp"

#include <fmt/format.h>

#include "core/Error.hpp"
#include "parallel/Reduce.hpp"

namespace gen4d::mpm {

void add_point_masses(MPI_Comm comm, const std::vector<PointMassConfig>& entries, Particles& p) {
  if (entries.empty()) return;
  // Every region's particle mass first (one collective), from the masses as seeded.
  std::vector<parallel::ExactSum> local(entries.size());
  std::vector<std::vector<std::size_t>> in(entries.size());
  for (std::size_t e = 0; e < entries.size(); ++e)
    for (std::size_t i = 0; i < p.size(); ++i)
      if (entries[e].region.contains({p.x[3 * i], p.x[3 * i + 1], p.x[3 * i + 2]})) {
        local[e].add(p.mass[i]);
        in[e].push_back(i);
      }
  std::vector<double> region_mass(entries.size(), 0.0);
  parallel::Reducer(comm).sum(local.data(), region_mass.data(), entries.size());
  for (std::size_t e = 0; e < entries.size(); ++e) {
    const PointMassConfig& pm = entries[e];
    if (!(region_mass[e] > 0))
      throw InputError(fmt::format(
          "{}: [[point_mass]] region [{}, {}, {}] .. [{}, {}, {}] holds no MPM particle (it must "
          "contain the reference position of at least one particle of the body)",
          pm.where, pm.region.lo[0], pm.region.lo[1], pm.region.lo[2], pm.region.hi[0],
          pm.region.hi[1], pm.region.hi[2]));
  }
  // Each particle's share of every entry, from its mass as seeded.
  std::vector<double> added(p.size(), 0.0);
  for (std::size_t e = 0; e < entries.size(); ++e) {
    const double per_kg = entries[e].mass / region_mass[e];
    for (std::size_t i : in[e]) added[i] += p.mass[i] * per_kg;
  }
  for (std::size_t i = 0; i < p.size(); ++i) p.mass[i] += added[i];
}

}  // namespace gen4d::mpm
