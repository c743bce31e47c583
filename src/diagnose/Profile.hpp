//! The profile likelihood of the selected fit's effect parameters (stage check): its problem,
//! Jacobian and threshold, the probes and each end's points (Check.cpp sets it up and reads the
//! intervals off; Profile.cpp computes the profile).
#pragma once

#include <Eigen/Dense>
#include <cstddef>
#include <utility>
#include <vector>

#include "diagnose/Pipeline.hpp"

namespace gen4d::diagnose {

//! The profile of the selected fit: its problem and Jacobian, the threshold, per effect parameter
//! the other parameters (their Jacobian columns and QR), the probes and each end's points.
struct Profile {
  std::vector<ParamSpec> specs;
  LsqProblem pr;
  std::size_t np = 0;  //!< parameters, baseline's included
  Eigen::MatrixXd J;   //!< the Jacobian at the fit
  double s2 = 0;       //!< residual variance of the fit
  double thr = 0;      //!< the threshold, in units of s2
  bool wide = false;   //!< the fit depends on its step: chi-square rough, ranges scanned
  double reach = 3.0;  //!< the quadratic's extrapolation limit (times a point's distance)
  double probe = 2.0;  //!< the probes' distance, in conditional standard errors
  std::vector<double> scan_lo, scan_hi;
  std::vector<std::vector<std::size_t>> others;
  std::vector<Eigen::MatrixXd> others_J;
  std::vector<Eigen::ColPivHouseholderQR<Eigen::MatrixXd>> others_qr;
  std::vector<std::pair<std::size_t, double>> at;  //!< the probes, (q, z_q), 2 per parameter
  //! Each end's profile points along its side, (z_j, chi-square above the fit in s2), the fit
  //! itself first, kept in order of distance from the fit (a point as far as one before it goes
  //! after it); and the chi-square of the last probe.
  struct Side {
    std::vector<std::pair<double, double>> pts;
    double last = 0;
  };
  std::vector<Side> sides;
  std::vector<double> best_z;  //!< the fit
};

//! A run's chi-square above the fit's, in units of s2 (a failed run: far beyond any).
double dchi_of(const State& s, const Profile& P, const Prediction& p);
//! The probes: two per effect parameter (index 2 q + side), sqrt(thr) (or 2) conditional standard
//! errors out, and their profile points (an unconstrained parameter's probes go to the bounds: its
//! standard error is infinite).
void probes(State& s, Profile& P);
//! Probes placed again nearer the threshold's crossing where the first landed far from it.
void refine_probes(State& s, Profile& P);
//! Where the profile of end idx crosses the threshold T, extrapolated at most max_reach times the
//! farthest point's distance; at_bound where the crossing is a bound of the range.
double crossing(const Profile& P, std::size_t idx, double T, double max_reach, bool& at_bound);

}  // namespace gen4d::diagnose
