//! The standard 3DGS point-cloud PLY (graphdeco-inria gaussian_model.py save_ply/load_ply).
//
// Properties, found by name in any order (binary little-endian float32, or ASCII):
// x y z [nx ny nz] f_dc_0..2 [f_rest_0..N-1] opacity scale_0..2 rot_0..3, with N = 0, 9, 24
// or 45 for SH degree 0..3 and f_rest channel-major; opacity a logit, scale a natural log,
// rot a quaternion w first, unnormalised (normalised on read). Other properties (of any scalar
// type) and elements after the vertex element are ignored; `comment` and `obj_info` lines too.
#pragma once

#include <string>

#include "gaussians/Splats.hpp"

namespace gen4d::gaussians {

//! Reads a 3DGS PLY in one read of the file. InputError naming the file and the property, row
//! (vertex index, from 0) or header line for: a missing or unreadable file, a bad header, a
//! missing property, a required property that is not float32, an f_rest count that is no SH
//! degree, a truncated body, a NaN or inf value, a zero quaternion, a log-scale whose exp is 0
//! or inf. Opacity logits saturate: the opacity is clamped into [DBL_MIN, 1 - 2^-53]. A
//! quaternion whose norm is within 2^-22 of 1 (unit to float32 rounding) is kept as stored, so
//! that reading back a written file gives exactly the values the file holds.
SplatSet read_splats_ply(const std::string& path);

//! Writes binary little-endian float32 in graphdeco's property order (normals written as 0),
//! through a temporary beside it and a rename: the name only ever holds a complete file.
//! RuntimeError naming the file when it cannot be written, or naming the splat when a value
//! does not fit (opacity outside (0, 1), a scale <= 0, a value beyond float32); std::logic_error
//! for inconsistent array lengths. A file this writer wrote, read and written again, is
//! byte-identical (for opacity logits of magnitude between about 1e-7 and 20 or exactly 0, and
//! log-scales of magnitude above about 1e-7 or exactly 0: elsewhere the activated doubles
//! cannot hold every float32 logit).
void write_splats_ply(const std::string& path, const SplatSet& splats);

}  // namespace gen4d::gaussians
