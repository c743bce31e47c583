//! Pinhole cameras in 3DGS's convention, from a cameras.json entry or an orbit around a point.
#pragma once

#include <array>
#include <string>
#include <vector>

namespace gen4d::gaussians {

//! A pinhole camera. rotation is camera-to-world, row-major, whose columns are the camera's
//! x (right), y (down) and z (forward) axes in world coordinates; pixel centres sit at integer
//! coordinates, principal point at the image centre (3DGS's ndc2Pix).
struct Camera {
  int width = 0, height = 0;
  double fx = 0, fy = 0;                    //!< focal lengths in pixels
  std::array<double, 3> position{0, 0, 0};  //!< camera centre, world
  std::array<double, 9> rotation{1, 0, 0, 0, 1, 0, 0, 0, 1};
  //! Horizontal / vertical field of view, 2 atan(width / (2 fx)) and likewise.
  double fov_x() const;
  double fov_y() const;
};

//! An orbit camera: looks at `center` from azimuth / elevation (degrees) at `radius`, `up` the
//! world's up axis; per-frame increments move it along the orbit (frame n uses azimuth +
//! n d_azimuth, and so on).
struct OrbitCamera {
  std::array<double, 3> center{0, 0, 0};
  std::array<double, 3> up{0, 0, 1};
  double azimuth = 0, elevation = 20, radius = 1;       //!< degrees, degrees, world units
  double d_azimuth = 0, d_elevation = 0, d_radius = 0;  //!< per frame
  double fov_y_degrees = 45;
  int width = 640, height = 480;
  Camera at_frame(long frame) const;
};

//! Every entry of a 3DGS cameras.json (id, img_name, width, height, position, rotation (3x3,
//! rows), fx, fy). InputError naming the file and the entry and key for malformed input.
std::vector<Camera> read_cameras_json(const std::string& path);
//! "FILE" or "FILE:INDEX" (default index 0); InputError naming the file for an index out of
//! range.
Camera read_camera_spec(const std::string& spec);
//! Writes entries in cameras.json's format (through a temporary and a rename).
void write_cameras_json(const std::string& path, const std::vector<Camera>& cameras);

}  // namespace gen4d::gaussians
