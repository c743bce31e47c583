//! Diagnose infers over the forward models of `src/forward` (the voxel FE model and the MPM
//! model): their vocabulary (Physics, Trace, ForwardModel, ModelTerms, ...) unqualified here.
#pragma once

#include "forward/Model.hpp"
#include "forward/MpmModel.hpp"
#include "forward/Terms.hpp"

namespace gen4d::diagnose {
using namespace gen4d::forward;  // NOLINT(google-build-using-namespace)
}  // namespace gen4d::diagnose
