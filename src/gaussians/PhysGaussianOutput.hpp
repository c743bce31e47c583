//! The files gs_simulation.py writes besides its images, and its cameras.json views carried into
//! the simulation space: what `gen4d run --physgaussian` needs to lay out its output as
//! PhysGaussian does.
#pragma once

#include <string>
#include <vector>

#include "gaussians/Camera.hpp"
#include "gaussians/PhysGaussianConfig.hpp"

namespace gen4d::gaussians {

//! The cameras of a trained model's cameras.json (trained space) in the simulation space of
//! `map`: position p -> map.to_sim(p), camera-to-world rotation C -> R C (R the map's rotation).
//! Image size and focal lengths are kept: the map is a similarity, so each view shows the same
//! picture of the mapped scene.
std::vector<Camera> cameras_to_simulation(const std::vector<Camera>& cameras,
                                          const PhysGaussianSimMap& map);

//! PhysGaussian's --output_ply file of frame `frame` (0: the rest state, k: after k frames),
//! relative to the output folder: simulation_ply/sim_<frame, 10 digits>.ply.
std::string simulation_ply_name(long frame);

//! Writes `xyz` (3 per point) as PhysGaussian's particle PLY: binary little-endian, element
//! vertex with float x, y, z only, through a temporary and a rename. RuntimeError when it
//! cannot be written.
void write_positions_ply(const std::string& path, const std::vector<double>& xyz);

//! Reads such a file back (any PLY whose only vertex properties are float x, y, z, binary
//! little-endian): 3 values per point. InputError naming the file for anything else.
std::vector<float> read_positions_ply(const std::string& path);

}  // namespace gen4d::gaussians
