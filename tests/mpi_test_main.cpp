// GoogleTest main for gen4d: initialises PETSc (and with it MPI), silences the
// listeners of ranks other than 0, and makes the exit code collective so one
// failing rank fails the test on every rank.
#include <gtest/gtest.h>
#include <mpi.h>
#include <petscsys.h>

#include "core/Log.hpp"

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  if (PetscInitialize(&argc, &argv, nullptr, nullptr) != 0) return 1;
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  gen4d::log::set_rank(rank);
  if (rank != 0) {
    auto& listeners = ::testing::UnitTest::GetInstance()->listeners();
    delete listeners.Release(listeners.default_result_printer());
  }
  int local = RUN_ALL_TESTS();
  int global = 0;
  MPI_Allreduce(&local, &global, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  PetscFinalize();
  return global;
}
