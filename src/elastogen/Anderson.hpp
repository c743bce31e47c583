//! Anderson acceleration of the RNN-1 outer loop (the local-global fixed point x -> x + dx),
//! as used for projective dynamics by Peng et al. 2018, with decomposition-independent sums.
#pragma once

#include <deque>
#include <vector>

#include "elastogen/VoxelSystem.hpp"
#include "parallel/Reduce.hpp"

namespace gen4d::elastogen {

//! Keeps the last `depth` differences of the fixed-point map G(x) = x + dx and its residual
//! f = dx, and proposes x_next = G(x) - dG gamma with gamma minimising ||f - dF gamma||.
//! The plain iteration converges linearly and slowly when bending or volume stiffness
//! dominates; the mix is a small least-squares problem solved identically on every rank.
class AndersonMixer {
 public:
  AndersonMixer(int depth, const VoxelSystem& sys, parallel::Reducer& reducer);

  //! Forgets the history (after a rejected step or at a new time step).
  void reset();
  //! Writes the next iterate into x_next on owned free nodes (x elsewhere). Returns true
  //! when history was used, false when x_next is the plain update x + delta.
  bool mix(const std::vector<double>& x, const std::vector<double>& delta,
           std::vector<double>& x_next);

 private:
  int depth_;
  const VoxelSystem& sys_;
  parallel::Reducer& red_;
  std::vector<double> prev_f_, prev_g_;
  bool has_prev_ = false;
  std::deque<std::vector<double>> df_, dg_;  // newest last
};

}  // namespace gen4d::elastogen
