//! The low-pass filter a recording went through, applied to the predictions alike: a
//! Butterworth filter run forwards and backwards (zero phase), as recordings are commonly
//! cleaned (scipy's filtfilt, MATLAB's filtfilt).
#pragma once

#include <cstddef>

namespace gen4d::forward {

//! Filters n samples spaced dt (s) in place, `stride` apart in x: a 4th-order Butterworth
//! low-pass at cutoff_hz (two bilinear-transform biquads, the cutoff prewarped) run forwards
//! and then backwards, the ends extended by odd reflection (3 cutoff periods, at most n - 1
//! samples) so the filter starts settled. Nothing when the cutoff is at or above Nyquist or
//! n < 3.
void lowpass_zero_phase(double* x, std::size_t n, std::size_t stride, double dt, double cutoff_hz);

}  // namespace gen4d::forward
