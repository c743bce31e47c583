//! run_diagnose: the diagnosis as a pipeline of stages over one State (Pipeline.hpp).
#include "diagnose/Diagnose.hpp"

#include "diagnose/Pipeline.hpp"

namespace gen4d::diagnose {

int run_diagnose(MPI_Comm comm, const Config& cfg, const DiagnoseOptions& opt) {
  State s(comm, cfg, opt);
  observe(s);
  calibrate(s);
  locate(s);
  screen(s);
  refit(s);
  diagnose::select(s);
  check(s);
  report(s);
  return 0;
}

}  // namespace gen4d::diagnose
