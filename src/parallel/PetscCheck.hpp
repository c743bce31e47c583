//! Turns a PETSc error code into a gen4d::RuntimeError naming the call.
#pragma once

#include <petscsys.h>

#include <string>

#include "core/Error.hpp"

namespace gen4d::parallel {

inline void check(PetscErrorCode ierr, const char* what) {
  if (ierr != 0) {
    const char* text = nullptr;
    PetscErrorMessage(ierr, &text, nullptr);
    throw RuntimeError(std::string("PETSc ") + what + " failed: " + (text ? text : "unknown"));
  }
}

}  // namespace gen4d::parallel
