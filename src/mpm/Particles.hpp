//! MPM particles of one rank, structure of arrays, with global ids that do not depend on the
//! decomposition, and the all-to-all redistribution used by migration and by ordered output.
#pragma once

#include <mpi.h>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include "mpm/Material.hpp"

namespace gen4d::mpm {

struct Particles {
  std::vector<std::int64_t> id;    //!< global id, dense 0..N-1 at seeding
  std::vector<double> x;           //!< 3 per particle, m
  std::vector<double> v;           //!< 3 per particle, m/s
  std::vector<double> C;           //!< 9 per particle (APIC affine velocity), 1/s, row-major
  std::vector<double> F;           //!< 9 per particle, elastic deformation gradient, row-major
  std::vector<double> state;       //!< kStateSize per particle (plastic / history scalars)
  std::vector<double> mass;        //!< kg
  std::vector<double> vol0;        //!< rest volume, m^3
  std::vector<std::uint8_t> flag;  //!< bit 0: frozen (not yet released); bit 1: kinematic

  //! Doubles per particle in a packed record (id stored as a double, exact below 2^53).
  static constexpr int kRecord = 1 + 3 + 3 + 9 + 9 + kStateSize + 2 + 1;

  std::size_t size() const { return id.size(); }
  void clear();
  void reserve(std::size_t n);
  //! Appends one particle at rest state (C = 0, F = I, state from init).
  void push_back(std::int64_t gid, const double* pos, const double* vel, double m, double v0,
                 const double* init_state);
  void pack(std::size_t i, double* rec) const;
  void append_packed(const double* rec);
  //! Keeps particles with keep[i] != 0, in order.
  void compact(const std::vector<std::uint8_t>& keep);
  //! Reorders by increasing id.
  void sort_by_id();
};

//! Sends every particle i to rank owner(i) (all-to-all); afterwards each rank holds the
//! particles it owns, received ones appended after the kept ones in source-rank order.
//! Collective. Returns the number of particles this rank sent away.
std::size_t redistribute(MPI_Comm comm, Particles& p, const std::function<int(std::size_t)>& owner);

}  // namespace gen4d::mpm
