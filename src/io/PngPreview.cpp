#include "io/PngPreview.hpp"

#include <png.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <csetjmp>
#include <cstdio>
#include <filesystem>

#include "core/Error.hpp"

namespace gen4d::io {
namespace {

using Vec3 = Eigen::Vector3d;
using Quad = std::array<std::size_t, 4>;

//! Faces between a solid voxel and an empty or outside one, as 4 node ids ordered so that
//! the right-hand normal points out of the solid.
std::vector<Quad> boundary_faces(const std::array<long, 3>& nodes,
                                 const std::vector<std::uint8_t>& occupancy) {
  const std::array<long, 3> cells = cell_dims(nodes);
  auto solid = [&](std::array<long, 3> c) {
    for (int a = 0; a < 3; ++a) {
      if (c[a] < 0 || c[a] >= cells[a]) return false;
    }
    return occupancy[(c[2] * cells[1] + c[1]) * cells[0] + c[0]] != 0;
  };
  std::vector<Quad> faces;
  for (long k = 0; k < cells[2]; ++k) {
    for (long j = 0; j < cells[1]; ++j) {
      for (long i = 0; i < cells[0]; ++i) {
        const std::array<long, 3> cell{i, j, k};
        if (!solid(cell)) continue;
        for (int a = 0; a < 3; ++a) {
          for (int side = 0; side < 2; ++side) {
            std::array<long, 3> neighbour = cell;
            neighbour[a] += side ? 1 : -1;
            if (solid(neighbour)) continue;
            const std::array<long, 4> face = cell_face_nodes(cell, a, side, nodes);
            Quad quad;
            for (int q = 0; q < 4; ++q) quad[q] = static_cast<std::size_t>(face[q]);
            faces.push_back(quad);
          }
        }
      }
    }
  }
  return faces;
}

struct Camera {
  Vec3 eye, right, up, forward;
  double focal = 1;  // pixels
  double near = 0;
};

//! Looks at the bounding sphere of the box [lo, hi] from 30 degrees up, a quarter turn off
//! the axes, with z up (gravity's axis).
Camera box_camera(const Vec3& lo, const Vec3& hi, int width, int height) {
  const Vec3 center = 0.5 * (lo + hi);
  const double radius = std::max(0.5 * (hi - lo).norm(), 1e-12);
  const double half_fov = 0.5 * 35.0 * M_PI / 180.0;
  const double azimuth = -55.0 * M_PI / 180.0, elevation = 30.0 * M_PI / 180.0;
  const Vec3 toward_eye(std::cos(elevation) * std::cos(azimuth),
                        std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
  Camera cam;
  cam.eye = center + 1.05 * radius / std::sin(half_fov) * toward_eye;
  cam.forward = -toward_eye;
  cam.right = cam.forward.cross(Vec3::UnitZ()).normalized();
  cam.up = cam.right.cross(cam.forward);
  cam.focal = 0.5 * std::min(width, height) / std::tan(half_fov);
  cam.near = 1e-3 * radius;
  return cam;
}

//! The camera of box_camera for the rest-state voxel surface.
Camera frame_camera(const std::vector<double>& rest, const std::vector<Quad>& faces, int width,
                    int height) {
  Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
  auto include = [&](std::size_t n) {
    const Vec3 p(rest[3 * n], rest[3 * n + 1], rest[3 * n + 2]);
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  };
  if (faces.empty()) {
    for (std::size_t n = 0; n < rest.size() / 3; ++n) include(n);
  }
  for (const Quad& quad : faces) {
    for (std::size_t n : quad) include(n);
  }
  return box_camera(lo, hi, width, height);
}

struct Image {
  int width, height;
  std::vector<Vec3> color;
  std::vector<double> inverse_depth;  // 0 = nothing drawn yet
};

Image background(int width, int height) {
  Image image{width, height, {}, std::vector<double>(std::size_t(width) * height, 0.0)};
  image.color.reserve(image.inverse_depth.size());
  const Vec3 sky_top(0.62, 0.74, 0.90), horizon(0.92, 0.93, 0.93), ground(0.42, 0.39, 0.35);
  for (int y = 0; y < height; ++y) {
    const double t = height > 1 ? double(y) / (height - 1) : 0.0;
    const Vec3 c = t < 0.55 ? sky_top + (horizon - sky_top) * (t / 0.55)
                            : horizon + (ground - horizon) * ((t - 0.55) / 0.45);
    for (int x = 0; x < width; ++x) image.color.push_back(c);
  }
  return image;
}

//! Fills triangle `s` (screen x, screen y, 1/depth per corner) where it is nearest so far.
void fill_triangle(Image& image, const std::array<Vec3, 3>& s, const Vec3& color) {
  auto edge = [](const Vec3& a, const Vec3& b, double px, double py) {
    return (b.x() - a.x()) * (py - a.y()) - (b.y() - a.y()) * (px - a.x());
  };
  const double area = edge(s[0], s[1], s[2].x(), s[2].y());
  if (std::abs(area) < 1e-12) return;
  const int x0 = std::max(0, int(std::floor(std::min({s[0].x(), s[1].x(), s[2].x()}))));
  const int x1 =
      std::min(image.width - 1, int(std::ceil(std::max({s[0].x(), s[1].x(), s[2].x()}))));
  const int y0 = std::max(0, int(std::floor(std::min({s[0].y(), s[1].y(), s[2].y()}))));
  const int y1 =
      std::min(image.height - 1, int(std::ceil(std::max({s[0].y(), s[1].y(), s[2].y()}))));
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const double px = x + 0.5, py = y + 0.5;
      const double w0 = edge(s[1], s[2], px, py) / area, w1 = edge(s[2], s[0], px, py) / area;
      const double w2 = 1.0 - w0 - w1;
      if (w0 < -1e-9 || w1 < -1e-9 || w2 < -1e-9) continue;
      // 1/depth is affine in screen space, so it interpolates exactly.
      const double inv_depth = w0 * s[0].z() + w1 * s[1].z() + w2 * s[2].z();
      const std::size_t pixel = std::size_t(y) * image.width + x;
      if (inv_depth <= image.inverse_depth[pixel]) continue;
      image.inverse_depth[pixel] = inv_depth;
      image.color[pixel] = color;
    }
  }
}

using Triangle = std::array<std::size_t, 3>;

//! Draws triangles of positions x with Lambert shading (both sides lit) over `image`.
void draw_triangles(Image& image, const std::vector<double>& x, const std::vector<Triangle>& tris,
                    const Camera& cam) {
  const int width = image.width, height = image.height;
  const Vec3 light = (-0.4 * cam.right + 0.8 * cam.up - 0.45 * cam.forward).normalized();
  const Vec3 material(0.86, 0.56, 0.34);
  auto node = [&](std::size_t n) { return Vec3(x[3 * n], x[3 * n + 1], x[3 * n + 2]); };
  for (const Triangle& tri : tris) {
    std::array<Vec3, 3> world{node(tri[0]), node(tri[1]), node(tri[2])}, screen;
    bool visible = true;
    for (int c = 0; c < 3; ++c) {
      const Vec3 q = world[c] - cam.eye;
      const double depth = q.dot(cam.forward);
      if (depth < cam.near) visible = false;
      screen[c] = Vec3(0.5 * width + cam.focal * q.dot(cam.right) / depth,
                       0.5 * height - cam.focal * q.dot(cam.up) / depth, 1.0 / depth);
    }
    Vec3 normal = (world[1] - world[0]).cross(world[2] - world[0]);
    if (!visible || normal.norm() == 0) continue;
    normal.normalize();
    // Light whichever side faces the camera: inverted elements must not turn black.
    if (normal.dot(cam.eye - world[0]) < 0) normal = -normal;
    const double lambert = std::max(0.0, normal.dot(light));
    fill_triangle(image, screen, material * (0.3 + 0.7 * lambert));
  }
}

Image render(const std::vector<double>& x, const std::vector<Quad>& faces, const Camera& cam,
             int width, int height) {
  Image image = background(width, height);
  std::vector<Triangle> tris;
  tris.reserve(2 * faces.size());
  for (const Quad& quad : faces) {
    tris.push_back({quad[0], quad[1], quad[2]});
    tris.push_back({quad[0], quad[2], quad[3]});
  }
  draw_triangles(image, x, tris, cam);
  return image;
}

//! 1, 2 or 5 times a power of ten, about a tenth of `extent`.
double grid_spacing(double extent) {
  const double raw = std::max(extent, 1e-12) / 10.0;
  const double decade = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0})
    if (m * decade >= raw) return m * decade;
  return 10.0 * decade;
}

//! A ground plane at height z with grid lines, written into colour and depth so that the
//! object occludes it; it fades out away from (cx, cy).
void draw_ground(Image& image, const Camera& cam, double z, double cx, double cy, double extent) {
  const double spacing = grid_spacing(extent), reach = 1.6 * extent;
  const Vec3 tile(0.66, 0.64, 0.60), line(0.38, 0.37, 0.35);
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      const Vec3 ray = cam.focal * cam.forward + (x + 0.5 - 0.5 * image.width) * cam.right -
                       (y + 0.5 - 0.5 * image.height) * cam.up;
      if (ray.z() >= 0) continue;
      const double t = (z - cam.eye.z()) / ray.z();
      if (t <= 0) continue;
      const Vec3 hit = cam.eye + t * ray;
      const double r = std::hypot(hit.x() - cx, hit.y() - cy);
      if (r > reach) continue;
      const double depth = (hit - cam.eye).dot(cam.forward);
      const std::size_t pixel = std::size_t(y) * image.width + x;
      auto near_line = [&](double v) {
        const double f = v / spacing - std::floor(v / spacing);
        return std::min(f, 1.0 - f) < 0.03;
      };
      const Vec3 c = near_line(hit.x()) || near_line(hit.y()) ? line : tile;
      const double fade = std::clamp((reach - r) / (0.5 * extent), 0.0, 1.0);
      image.color[pixel] = fade * c + (1.0 - fade) * image.color[pixel];
      image.inverse_depth[pixel] = 1.0 / depth;
    }
  }
}

void png_fail(png_structp png, png_const_charp message) {
  std::snprintf(static_cast<char*>(png_get_error_ptr(png)), 256, "%s", message);
  png_longjmp(png, 1);
}

//! Encodes 8-bit RGB rows; kept free of C++ objects because libpng reports errors by longjmp.
bool encode_png(std::FILE* file, int width, int height, const std::uint8_t* rgb, char* error) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, error, png_fail, nullptr);
  if (png == nullptr) return false;
  png_infop info = png_create_info_struct(png);
  if (info == nullptr) {
    png_destroy_write_struct(&png, nullptr);
    return false;
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return false;
  }
  png_init_io(png, file);
  png_set_IHDR(png, info, width, height, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  for (int y = 0; y < height; ++y) {
    png_write_row(png, const_cast<png_bytep>(rgb + std::size_t(3) * width * y));
  }
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return true;
}

void write_png(const std::string& path, const Image& image) {
  std::vector<std::uint8_t> rgb;
  rgb.reserve(3 * image.color.size());
  for (const Vec3& c : image.color) {
    for (int k = 0; k < 3; ++k)
      rgb.push_back(std::uint8_t(std::lround(255 * std::clamp(c[k], 0.0, 1.0))));
  }
  write_png_rgb(path, image.width, image.height, rgb);
}

//! Surface and camera shared by every frame of a sequence.
struct Scene {
  std::vector<Quad> faces;
  Camera camera;
};

void check_size(int width, int height) {
  if (width <= 0 || height <= 0 || width > 16384 || height > 16384) {
    throw InputError("preview size " + std::to_string(width) + "x" + std::to_string(height) +
                     " must be between 1 and 16384 pixels per side");
  }
}

Scene make_scene(const FrameReader& reader, int width, int height) {
  check_size(width, height);
  Scene scene;
  scene.faces = boundary_faces(reader.node_dims(), reader.read_occupancy());
  scene.camera = frame_camera(reader.read_position(0), scene.faces, width, height);
  return scene;
}

}  // namespace

void write_png_rgb(const std::string& path, int width, int height,
                   const std::vector<std::uint8_t>& rgb) {
  if (width <= 0 || height <= 0 || rgb.size() != std::size_t(3) * width * height) {
    throw RuntimeError("cannot write " + path + " (pixel buffer does not match " +
                       std::to_string(width) + "x" + std::to_string(height) + ")");
  }
  const std::string temp = path + ".tmp";
  std::FILE* file = std::fopen(temp.c_str(), "wb");
  if (file == nullptr) throw RuntimeError("cannot create " + temp);
  char error[256] = "write error";
  bool ok = encode_png(file, width, height, rgb.data(), error);
  ok = std::fclose(file) == 0 && ok;
  if (!ok) {
    std::remove(temp.c_str());
    throw RuntimeError("cannot write " + path + " (" + error + ")");
  }
  if (std::rename(temp.c_str(), path.c_str()) != 0) {
    std::remove(temp.c_str());
    throw RuntimeError("cannot rename " + temp + " to " + path);
  }
}

void render_frame_png(const FrameReader& reader, int frame, const std::string& png_path, int width,
                      int height) {
  const Scene scene = make_scene(reader, width, height);
  write_png(png_path,
            render(reader.read_position(frame), scene.faces, scene.camera, width, height));
}

std::vector<std::string> render_frames(const FrameReader& reader, const std::vector<int>& frames,
                                       const std::string& out_dir, int width, int height) {
  const Scene scene = make_scene(reader, width, height);
  std::vector<std::string> paths;
  for (int frame : frames) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%06d.png", frame);
    paths.push_back((std::filesystem::path(out_dir) / name).string());
    write_png(paths.back(),
              render(reader.read_position(frame), scene.faces, scene.camera, width, height));
  }
  return paths;
}

std::vector<std::string> render_surface_frames(const std::vector<SurfaceFrameFile>& sequence,
                                               const std::vector<int>& chosen,
                                               const std::string& out_dir, int width, int height,
                                               bool ground) {
  check_size(width, height);
  // One camera for the whole sequence: the bounding box of every frame.
  Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
  for (const SurfaceFrameFile& f : sequence) {
    const SurfaceMesh mesh = read_surface(f.path);
    for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
      const Vec3 p(mesh.xyz[3 * v], mesh.xyz[3 * v + 1], mesh.xyz[3 * v + 2]);
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
  }
  if ((lo.array() > hi.array()).any()) lo = hi = Vec3::Zero();
  const Camera camera = box_camera(lo, hi, width, height);
  const double extent = std::max({hi.x() - lo.x(), hi.y() - lo.y(), hi.z() - lo.z(), 1e-12});
  std::vector<std::string> paths;
  for (int position : chosen) {
    const SurfaceFrameFile& f = sequence.at(static_cast<std::size_t>(position));
    const SurfaceMesh mesh = read_surface(f.path);
    std::vector<Triangle> tris;
    tris.reserve(mesh.triangles.size());
    for (const auto& t : mesh.triangles)
      tris.push_back({std::size_t(t[0]), std::size_t(t[1]), std::size_t(t[2])});
    Image image = background(width, height);
    if (ground)
      draw_ground(image, camera, lo.z(), 0.5 * (lo.x() + hi.x()), 0.5 * (lo.y() + hi.y()), extent);
    draw_triangles(image, mesh.xyz, tris, camera);
    char name[40];
    std::snprintf(name, sizeof name, "surface_%06ld.png", f.index);
    paths.push_back((std::filesystem::path(out_dir) / name).string());
    write_png(paths.back(), image);
  }
  return paths;
}

}  // namespace gen4d::io
