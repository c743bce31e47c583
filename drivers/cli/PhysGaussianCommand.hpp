//! PhysGaussian's scenes as gen4d runs: a JSON config (config/*.json) and a trained model folder
//! become a gen4d deck and the simulated selection of Gaussians.
#pragma once

#include <mpi.h>

#include <string>

namespace gen4d::cli {

//! The trained PLY of a 3DGS model folder, as gs_simulation.py finds it:
//! DIR/point_cloud/iteration_<largest>/point_cloud.ply. InputError naming the folder otherwise.
std::string physgaussian_model_ply(const std::string& model_path);

//! Reads `config` and the model's PLY, preprocesses as PhysGaussian does and writes
//! out_dir/object.ply (the selection, in simulation space) and out_dir/deck.toml (through
//! temporaries), logging each mapping note. Collective: every rank validates, rank 0 writes.
//! Returns the deck's path. Bad config or model: InputError before anything is written.
std::string convert_physgaussian(MPI_Comm comm, const std::string& config,
                                 const std::string& model_path, const std::string& out_dir);

}  // namespace gen4d::cli
