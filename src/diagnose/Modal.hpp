// Modal frequencies of a recorded (or simulated) free motion, for starting fits in the basin
// of the right phase of more than one mode.
#pragma once

#include <vector>

#include "diagnose/Fit.hpp"

namespace gen4d::diagnose {

//! The two lowest angular frequencies of the motion after t_from, shared by all channels.
struct ModalFrequencies {
  double omega1 = 0;     //!< dominant frequency (rad/s); 0 when too few samples
  double omega2 = 0;     //!< next mode (rad/s); 0 when none stands out of the noise
  double drop = 0;       //!< chi-square that omega2's sinusoids remove
  double threshold = 0;  //!< what noise alone could remove (drop must exceed it)
};

//! Sum over channel components (positions; accelerometers only when there is no marker) of
//! the noise-weighted least-squares misfit of y after t_from by a constant and a cosine and a
//! sine at each frequency of `omegas`, amplitudes free per component (variable projection).
double sinusoid_misfit(const Observations& obs, const std::vector<double>& y, double t_from,
                       const std::vector<double>& omegas);

//! omega1 is the frequency that best explains y after t_from (searched within 30 % of
//! `omega1_guess`, e.g. from mean crossings); omega2 the one that best explains what remains
//! with omega1 and its first harmonic 2 omega1 (which large rotations put into the motion
//! along the axis) in the basis, searched from 1.5 omega1 to 0.9 of the Nyquist frequency of
//! the median sample spacing, away from 3 omega1 (cubic stiffening). omega2 is kept when it
//! removes more chi-square than the largest of that many independent noise-only frequencies
//! would (about 2 m + 10 sqrt(4 m) + 25 for m channel components), else it is 0. With
//! omega2_guess > 0 (a simulation of a recording whose omega2 is known) omega2 is searched
//! within 35 % of it only.
ModalFrequencies modal_frequencies(const Observations& obs, const std::vector<double>& y,
                                   double t_from, double omega1_guess, double omega2_guess = 0);

}  // namespace gen4d::diagnose
