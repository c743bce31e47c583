//! A run's [render] table (core/Config.hpp's RenderConfig): the camera of each output frame,
//! one PNG per frame (OUT/png/frame_NNNNNN.png, or gs_simulation.py's OUT/0000.png, ... with
//! render.layout = "physgaussian"), the static scenery drawn with every frame, and the MP4 at
//! the end. Both solvers use it; they only supply each rank's deformed splats.
#pragma once

#include <array>
#include <string>

#include "core/Config.hpp"
#include "gaussians/Camera.hpp"
#include "gaussians/Render.hpp"
#include "gaussians/Splats.hpp"
#include "parallel/Comm.hpp"

namespace gen4d::gaussians {

//! The orbit camera of a [render] table at output frame `index` (render.camera = "orbit").
Camera orbit_camera(const RenderConfig& r, long index);

class RunRenderer {
 public:
  //! Reads the cameras.json entry where render.camera names one and render.scenery (each rank
  //! keeps its share of the scenery's splats). InputError naming the file. Collective.
  RunRenderer(MPI_Comm comm, const RenderConfig& r);

  //! For render.camera = "auto": the orbit's centre and radius frame the object at rest, the
  //! central box of `splats` (see central_box) joined with [lo, hi] (the other parts' bounds;
  //! ignored where lo > hi). No effect for the other cameras.
  void frame_object(const SplatSet& splats, const std::array<double, 3>& lo,
                    const std::array<double, 3>& hi);

  //! Creates the image folder (out_dir/png, or out_dir itself for the physgaussian layout) and
  //! removes its images of frames after `keep_up_to` (-1: every image, for a fresh run; a restart
  //! keeps the frames its frame file keeps). Collective; RuntimeError on every rank when the
  //! folder cannot be prepared.
  void open(const std::string& out_dir, long keep_up_to);
  //! The camera of output frame `index`.
  Camera camera(long index) const;
  //! Draws the union of every rank's `local` splats and the scenery for output frame `index`
  //! into frame_image_name(layout, index) (rank 0 writes it through a temporary); nothing for
  //! frame 0 under the physgaussian layout. Collective.
  void render(long index, const SplatFrame& local);
  //! With render.video = "mp4", assembles the layout's images, in frame order, into
  //! out_dir/render.mp4 (out_dir/output.mp4 for the physgaussian layout) at render.fps, else
  //! 1 / frame_interval frames per second within 1 to 60, where ffmpeg is installed.
  //! Collective.
  void finish(double frame_interval);
  //! The video's frame rate for output frames `frame_interval` s apart.
  double fps(double frame_interval) const;

  const std::string& png_dir() const { return png_dir_; }
  long images() const { return images_; }

 private:
  MPI_Comm comm_;
  int rank_ = 0;
  RenderConfig cfg_;
  Camera fixed_;  //!< the cameras.json entry (render.camera != "orbit")
  RenderOptions options_;
  SplatFrame scenery_;  //!< this rank's share of render.scenery
  std::string out_dir_, png_dir_;
  long images_ = 0;
};

//! "frame_NNNNNN.png" of output frame `index`, and the index of such a name (-1 for others).
std::string frame_png_name(long index);
long frame_png_index(const std::string& name);

//! gs_simulation.py's name of its image `image` (the state after image + 1 frames):
//! f"{image}.png".rjust(8, "0"), so 0000.png, 0001.png, ..., 9999.png, 10000.png. The index of
//! such a name, or -1 for others.
std::string physgaussian_png_name(long image);
long physgaussian_png_index(const std::string& name);

//! The image of output frame `index` relative to the output folder under render.layout
//! ("gen4d" | "physgaussian"); "" where the layout draws no image of that frame.
std::string frame_image_name(const std::string& layout, long index);
//! The output frame of such a path relative to the output folder (-1 for other files).
long frame_image_index(const std::string& layout, const std::string& name);

//! `a` and `b` in one frame: the lower SH degree raised to the higher one (zero coefficients)
//! and identity sh_rotation added to the splats lacking it where the other frame has it, which
//! leaves every splat's colour unchanged.
SplatFrame merge_frames(const SplatFrame& a, const SplatFrame& b);

}  // namespace gen4d::gaussians
