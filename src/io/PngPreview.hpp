//! Software-rendered PNG previews of stored frames, to look at a run without a viewer.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "io/FrameReader.hpp"
#include "io/SurfaceIO.hpp"

namespace gen4d::io {

//! Writes 8-bit RGB pixels (3 per pixel, rows top to bottom) as a PNG through a temporary and a
//! rename, so the name only ever holds a complete image. Throws RuntimeError.
void write_png_rgb(const std::string& path, int width, int height,
                   const std::vector<std::uint8_t>& rgb);

//! Renders frame `frame` (position in reader.frames()) of the solid's surface, the faces
//! between solid voxels and empty space at their deformed node positions, to a width x height
//! RGB PNG. The camera frames the rest-state (frame 0) solid from an elevated three-quarter
//! view, identical for every frame so a sequence is comparable. The file appears under its
//! name only once complete; failures to write it are RuntimeErrors, bad frames InputErrors.
void render_frame_png(const FrameReader& reader, int frame, const std::string& png_path, int width,
                      int height);

//! Renders each of `frames` to out_dir/frame_<frame, 6 digits>.png; returns the paths.
std::vector<std::string> render_frames(const FrameReader& reader, const std::vector<int>& frames,
                                       const std::string& out_dir, int width, int height);

//! Renders the surface files at positions `chosen` of `sequence` (as listed by
//! list_surface_sequence) as shaded triangles to out_dir/surface_<index, 6 digits>.png, with
//! a z-buffer and Lambert shading. The camera frames the bounding box of every file of the
//! sequence, so the images of a sequence are comparable; `ground` adds a grid on the plane
//! under the lowest point. Bad files are InputErrors naming the file; returns the paths.
std::vector<std::string> render_surface_frames(const std::vector<SurfaceFrameFile>& sequence,
                                               const std::vector<int>& chosen,
                                               const std::string& out_dir, int width, int height,
                                               bool ground);

}  // namespace gen4d::io
