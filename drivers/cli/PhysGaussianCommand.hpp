//! PhysGaussian's scenes as gen4d runs: a JSON config (config/*.json) and a trained model folder
//! become a gen4d deck and the simulated selection of Gaussians.
#pragma once

#include <mpi.h>

#include <string>

namespace gen4d::cli {

//! The trained PLY of a 3DGS model folder, as gs_simulation.py finds it:
//! DIR/point_cloud/iteration_<largest>/point_cloud.ply. InputError naming the folder otherwise.
std::string physgaussian_model_ply(const std::string& model_path);

//! Reads `config`, the model's PLY and its cameras.json (where there is one), preprocesses as
//! PhysGaussian does and writes out_dir/object.ply (the selection, in simulation space),
//! out_dir/scenery.ply (the Gaussians outside sim_area, same space, where there are any),
//! out_dir/sim_cameras.json (the model's cameras in simulation space) and out_dir/deck.toml
//! (through temporaries), logging each mapping note. Collective: every rank validates, rank 0
//! writes. Returns the deck's path. Bad config, model or cameras.json: InputError before
//! anything is written.
std::string convert_physgaussian(MPI_Comm comm, const std::string& config,
                                 const std::string& model_path, const std::string& out_dir);

//! gs_simulation.py's --output_ply files from a finished run's out_dir/particles.h5: for every
//! frame k, out_dir/simulation_ply/sim_<k, 10 digits>.ply with the positions of the alive
//! particles in id order (float x, y, z). Collective; rank 0 reads and writes; RuntimeError on
//! every rank when it fails.
void write_physgaussian_plys(MPI_Comm comm, const std::string& out_dir);

}  // namespace gen4d::cli
