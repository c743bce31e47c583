//! MPM particles of one rank, structure of arrays, with global ids that do not depend on the
//! decomposition, and the all-to-all redistribution used by migration and by ordered output.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "mpm/Kernels.hpp"
#include "mpm/Material.hpp"
#include "parallel/Comm.hpp"

namespace gen4d::mpm {

struct Particles {
  std::vector<std::int64_t> id;        //!< global id, dense 0..N-1 at seeding
  std::vector<double> x;               //!< 3 per particle, m
  std::vector<double> v;               //!< 3 per particle, m/s
  std::vector<double> C;               //!< 9 per particle (APIC affine velocity), 1/s, row-major
  std::vector<double> F;               //!< 9 per particle, elastic deformation gradient, row-major
  std::vector<double> state;           //!< kStateSize per particle (plastic / history scalars)
  std::vector<double> mass;            //!< kg
  std::vector<double> vol0;            //!< rest volume, m^3
  std::vector<std::uint8_t> flag;      //!< bit 0: frozen (not yet released); bit 1: kinematic
  std::vector<std::uint8_t> material;  //!< slot of the run's MaterialSet (0 with one material)
  //! extra_width doubles per particle carried with it through migration, checkpoints and
  //! restart, whose meaning the run defines (the splat attributes of mpm/SplatParticles.hpp);
  //! empty when extra_width is 0.
  std::vector<double> extra;
  int extra_width = 0;

  //! Doubles per particle in a packed record of the solver's attributes (id stored as a
  //! double, exact below 2^53; `extra` is not part of it).
  static constexpr int kRecord = 1 + 3 + 3 + 9 + 9 + kStateSize + 2 + 2;

  std::size_t size() const { return id.size(); }
  void clear();
  void reserve(std::size_t n);
  //! Appends one particle at rest state (C = 0, F = I, state from init) with extra_width
  //! values from `extra_values` (zeros when null).
  void push_back(std::int64_t gid, const double* pos, const double* vel, double m, double v0,
                 const double* init_state, const double* extra_values = nullptr);
  //! Appends every particle of `other`, whose extra_width must equal this one's
  //! (std::logic_error otherwise).
  void append(const Particles& other);
  //! The kRecord values of particle i.
  void pack(std::size_t i, double* rec) const;
  //! Doubles of pack_motion's record.
  static constexpr int kMotionRecord = 1 + 3 + 3;
  //! id, x and v of particle i: the first kMotionRecord values of pack's record.
  void pack_motion(std::size_t i, double* rec) const;
  //! Why the arrays disagree in length with size() and extra_width; "" when consistent.
  std::string inconsistency() const;
  //! Keeps particles with keep[i] != 0, in order.
  void compact(const std::vector<std::uint8_t>& keep);
  //! Reorders by increasing id.
  void sort_by_id();
};

//! Calls fn(width, column...) for every per-particle array of the particle sets `p` (the
//! same array of each), in a fixed order with `extra` last (its width from the first set).
template <class Fn, class First, class... Rest>
void for_each_column(Fn&& fn, First& p, Rest&... q) {
  fn(1, p.id, q.id...);
  fn(3, p.x, q.x...);
  fn(3, p.v, q.v...);
  fn(9, p.C, q.C...);
  fn(9, p.F, q.F...);
  fn(kStateSize, p.state, q.state...);
  fn(1, p.mass, q.mass...);
  fn(1, p.vol0, q.vol0...);
  fn(1, p.flag, q.flag...);
  fn(1, p.material, q.material...);
  fn(p.extra_width, p.extra, q.extra...);
}

using kernels::advance_deformation;

//! Sends every particle i, every attribute and `extra` included, to rank dest[i]
//! (parallel::RowExchange); afterwards each rank holds the particles it owns: the kept ones
//! (the last of them moved into the gaps of those sent), then the received ones in source-rank
//! order. Collective. Returns the number of particles this rank sent away.
std::size_t redistribute(MPI_Comm comm, Particles& p, const std::vector<int>& dest);

}  // namespace gen4d::mpm
