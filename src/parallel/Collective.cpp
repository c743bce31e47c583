#include "parallel/Collective.hpp"

#include <exception>

#include "core/Error.hpp"

namespace gen4d::parallel {

void on_rank0(MPI_Comm comm, const std::string& elsewhere, const std::function<void()>& work) {
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  std::string error;
  if (rank == 0) {
    try {
      work();
    } catch (const std::exception& e) {
      error = e.what();
    }
  }
  int failed = error.empty() ? 0 : 1;
  MPI_Bcast(&failed, 1, MPI_INT, 0, comm);
  if (failed) throw RuntimeError(rank == 0 ? error : elsewhere);
}

}  // namespace gen4d::parallel
