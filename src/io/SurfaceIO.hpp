//! Triangle-surface files for artists' tools: a per-frame sequence of PLY (binary little-endian)
//! or Wavefront OBJ (ASCII) files, written atomically, and readers for both.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace gen4d::io {

//! One frame of a surface: vertex positions (3 interleaved doubles per vertex) and triangles
//! (0-based vertex indices, counter-clockwise seen from outside).
struct SurfaceMesh {
  std::vector<double> xyz;
  std::vector<std::array<std::int32_t, 3>> triangles;
  std::vector<std::string> comments;  //!< free text lines ("comment" in PLY, "#" in OBJ)

  std::size_t vertex_count() const { return xyz.size() / 3; }
};

enum class SurfaceFormat { Ply, Obj };

//! "ply" or "obj" (the file extension without the dot).
const char* surface_extension(SurfaceFormat format);
//! Parses "ply" / "obj"; false for anything else.
bool parse_surface_format(const std::string& name, SurfaceFormat& format);

//! Folder of the sequence inside a run's output directory, and the name of one frame's file:
//! "surface_<index, 6 digits>.<ext>".
inline constexpr const char* kSurfaceDir = "surface";
std::string surface_file_name(long index, SurfaceFormat format);

//! Writes `mesh` to `path` through a temporary in the same folder and a rename, so the final
//! name only ever holds a complete file. PLY stores positions as float64 and faces as
//! `list uchar int vertex_indices`; OBJ writes every coordinate in its shortest form that
//! reads back to the same double. Throws RuntimeError when it cannot be written.
void write_surface(const std::string& path, const SurfaceMesh& mesh, SurfaceFormat format);

//! The file as bytes, exactly as write_surface stores it.
std::string surface_bytes(const SurfaceMesh& mesh, SurfaceFormat format);

//! Reads a PLY (ascii or binary_little_endian 1.0; vertex x/y/z of any numeric type, faces as
//! a list property vertex_indices or vertex_index, polygons fan-triangulated; other elements
//! and properties skipped) or an OBJ (`v` and `f` records, v/vt/vn and negative indices).
//! Dispatches on the extension. Every defect is an InputError naming the file and the header
//! line, element and index, or OBJ line at fault.
SurfaceMesh read_surface(const std::string& path);
SurfaceMesh read_ply(const std::string& path);
SurfaceMesh read_obj_surface(const std::string& path);

//! One file of a sequence found on disk.
struct SurfaceFrameFile {
  long index = 0;
  std::string path;
};
//! The surface_NNNNNN.ply / .obj files in `dir`, ordered by index (empty when there are none
//! or `dir` does not exist). Temporaries and other names are ignored.
std::vector<SurfaceFrameFile> list_surface_sequence(const std::string& dir);

//! Deletes the sequence files in `dir` whose index is greater than `keep_up_to` (-1 deletes
//! every one), and leftover temporaries of interrupted writes. Returns how many were removed.
//! Throws RuntimeError when one cannot be removed.
int prune_surface_sequence(const std::string& dir, long keep_up_to);

}  // namespace gen4d::io
