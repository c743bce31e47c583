//! A run's [render] table (core/Config.hpp's RenderConfig): the camera of each output frame,
//! one PNG per frame under OUT/png/frame_NNNNNN.png and the MP4 at the end. Both solvers use it;
//! they only supply each rank's deformed splats.
#pragma once

#include <mpi.h>

#include <array>
#include <string>

#include "core/Config.hpp"
#include "gaussians/Camera.hpp"
#include "gaussians/Render.hpp"
#include "gaussians/Splats.hpp"

namespace gen4d::gaussians {

//! The orbit camera of a [render] table at output frame `index` (render.camera = "orbit").
Camera orbit_camera(const RenderConfig& r, long index);

class RunRenderer {
 public:
  //! Reads the cameras.json entry where render.camera names one (InputError naming the file).
  RunRenderer(MPI_Comm comm, const RenderConfig& r);

  //! For render.camera = "auto": the orbit's centre and radius frame the object at rest, the
  //! central box of `splats` (see central_box) joined with [lo, hi] (the other parts' bounds;
  //! ignored where lo > hi). No effect for the other cameras.
  void frame_object(const SplatSet& splats, const std::array<double, 3>& lo,
                    const std::array<double, 3>& hi);

  //! Creates out_dir/png and removes its images of frames after `keep_up_to` (-1: every image,
  //! for a fresh run; a restart keeps the frames its frame file keeps). Collective; RuntimeError
  //! on every rank when the folder cannot be prepared.
  void open(const std::string& out_dir, long keep_up_to);
  //! The camera of output frame `index`.
  Camera camera(long index) const;
  //! Draws the union of every rank's `local` splats for output frame `index` into
  //! png/frame_NNNNNN.png (rank 0 writes it through a temporary). Collective.
  void render(long index, const SplatFrame& local);
  //! With render.video = "mp4", assembles png/ into out_dir/render.mp4 at 1 / frame_interval
  //! frames per second (within 1 to 60) where ffmpeg is installed. Collective.
  void finish(double frame_interval);

  const std::string& png_dir() const { return png_dir_; }
  long images() const { return images_; }

 private:
  MPI_Comm comm_;
  int rank_ = 0;
  RenderConfig cfg_;
  Camera fixed_;  //!< the cameras.json entry (render.camera != "orbit")
  RenderOptions options_;
  std::string out_dir_, png_dir_;
  long images_ = 0;
};

//! "frame_NNNNNN.png" of output frame `index`, and the index of such a name (-1 for others).
std::string frame_png_name(long index);
long frame_png_index(const std::string& name);

}  // namespace gen4d::gaussians
