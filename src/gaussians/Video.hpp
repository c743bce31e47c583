//! Image sequences to video through the ffmpeg executable, when it is installed.
#pragma once

#include <string>
#include <vector>

namespace gen4d::gaussians {

//! The ffmpeg executable on PATH, or "" when there is none.
std::string find_ffmpeg();

//! Encodes the PNG files of `png_dir` (every *.png, in name order) at `fps` frames per second
//! into `out_mp4` (H.264 with libx264 where ffmpeg has it, else MPEG-4 part 2; yuv420p, sizes
//! rounded down to even), through a temporary and a rename. Returns out_mp4, or "" (and logs a
//! note) when ffmpeg is not on PATH. InputError when png_dir holds no PNG or fps is not
//! positive; RuntimeError when ffmpeg fails.
std::string assemble_mp4(const std::string& png_dir, double fps, const std::string& out_mp4);

//! The same for the PNG files `pngs`, in the order given (every one shown for 1 / fps s).
std::string assemble_mp4(const std::vector<std::string>& pngs, double fps,
                         const std::string& out_mp4);

}  // namespace gen4d::gaussians
