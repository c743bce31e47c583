#include "gaussians/Camera.hpp"

#include <cmath>
#include <string>

#include "core/Error.hpp"
#include "gaussians/Json.hpp"

namespace gen4d::gaussians {

namespace {
constexpr double kPi = 3.14159265358979323846;
using V3 = std::array<double, 3>;

V3 sub(const V3& a, const V3& b) {
  return {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
}
V3 scaled(const V3& a, double s) {
  return {a[0] * s, a[1] * s, a[2] * s};
}
V3 add(const V3& a, const V3& b) {
  return {a[0] + b[0], a[1] + b[1], a[2] + b[2]};
}
double dot(const V3& a, const V3& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
V3 cross(const V3& a, const V3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
V3 normalized(const V3& a) {
  return scaled(a, 1.0 / std::sqrt(dot(a, a)));
}
}  // namespace

double Camera::fov_x() const {
  return 2.0 * std::atan(width / (2.0 * fx));
}
double Camera::fov_y() const {
  return 2.0 * std::atan(height / (2.0 * fy));
}

Camera OrbitCamera::at_frame(long frame) const {
  const double n = static_cast<double>(frame);
  const double az = (azimuth + n * d_azimuth) * kPi / 180.0;
  const double el = (elevation + n * d_elevation) * kPi / 180.0;
  const double r = radius + n * d_radius;
  const double up_len = std::sqrt(dot(up, up));
  if (!(up_len > 0) || !std::isfinite(up_len))
    throw InputError("orbit camera: the up axis must be a non-zero finite vector");
  if (!(r > 0) || !std::isfinite(r))
    throw InputError("orbit camera: the radius at frame " + std::to_string(frame) +
                     " is not positive (" + std::to_string(r) + ")");
  if (width < 1 || height < 1) throw InputError("orbit camera: width and height must be positive");
  if (!(fov_y_degrees > 0 && fov_y_degrees < 180))
    throw InputError("orbit camera: fov_y must lie in (0, 180) degrees");
  // A right-handed frame (e1, e2, u) around the up axis; azimuth 0 lies along e1, the world
  // axis least aligned with up, projected.
  const V3 u = scaled(up, 1.0 / up_len);
  const V3 a = std::fabs(u[0]) > 0.9 ? V3{0, 1, 0} : V3{1, 0, 0};
  const V3 e1 = normalized(sub(a, scaled(u, dot(a, u))));
  const V3 e2 = cross(u, e1);
  const V3 radial =
      add(scaled(add(scaled(e1, std::cos(az)), scaled(e2, std::sin(az))), std::cos(el)),
          scaled(u, std::sin(el)));
  Camera cam;
  cam.width = width;
  cam.height = height;
  cam.fy = height / (2.0 * std::tan(fov_y_degrees * kPi / 360.0));
  cam.fx = cam.fy;
  for (int i = 0; i < 3; ++i) cam.position[i] = center[i] + r * radial[i];
  // Forward towards the centre; right along the orbit's direction of increasing azimuth (the
  // horizontal right vector for |elevation| < 90, and still defined looking along up); down
  // completes the right-handed frame.
  const V3 z = scaled(radial, -1.0);
  const V3 x = add(scaled(e1, -std::sin(az)), scaled(e2, std::cos(az)));
  const V3 y = cross(z, x);
  for (int i = 0; i < 3; ++i) {
    cam.rotation[3 * i + 0] = x[i];
    cam.rotation[3 * i + 1] = y[i];
    cam.rotation[3 * i + 2] = z[i];
  }
  return cam;
}

namespace {

std::string where(const std::string& path, const JsonValue& v, std::size_t entry) {
  return path + ":" + std::to_string(v.line()) + ": camera entry " + std::to_string(entry);
}

const JsonValue& member(const std::string& path, const JsonValue& e, std::size_t entry,
                        const char* key, JsonValue::Type type) {
  const JsonValue* v = e.find(key);
  if (!v) throw InputError(where(path, e, entry) + ": missing key \"" + key + "\"");
  if (v->type() != type)
    throw InputError(where(path, *v, entry) + ": key \"" + key + "\" must be a " +
                     json_type_name(type) + ", not a " + json_type_name(v->type()));
  return *v;
}

double number(const std::string& path, const JsonValue& v, std::size_t entry,
              const std::string& key) {
  if (!v.is_number())
    throw InputError(where(path, v, entry) + ": key \"" + key + "\" must hold numbers, not a " +
                     json_type_name(v.type()));
  return v.as_number();
}

int positive_int(const std::string& path, const JsonValue& e, std::size_t entry, const char* key) {
  const JsonValue& v = member(path, e, entry, key, JsonValue::Type::Number);
  const double x = v.as_number();
  if (!(x >= 1 && x <= 65536 && x == std::floor(x)))
    throw InputError(where(path, v, entry) + ": key \"" + key +
                     "\" must be a positive integer of at most 65536");
  return static_cast<int>(x);
}

double positive(const std::string& path, const JsonValue& e, std::size_t entry, const char* key) {
  const JsonValue& v = member(path, e, entry, key, JsonValue::Type::Number);
  if (!(v.as_number() > 0))
    throw InputError(where(path, v, entry) + ": key \"" + key + "\" must be positive");
  return v.as_number();
}

}  // namespace

std::vector<Camera> read_cameras_json(const std::string& path) {
  const JsonValue doc = read_json_file(path);
  if (!doc.is_array())
    throw InputError(path + ":" + std::to_string(doc.line()) +
                     ": a cameras.json file holds an array of camera entries, not a " +
                     json_type_name(doc.type()));
  std::vector<Camera> out;
  const auto& entries = doc.items();
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const JsonValue& e = entries[i];
    if (!e.is_object())
      throw InputError(where(path, e, i) + ": must be an object, not a " +
                       json_type_name(e.type()));
    Camera c;
    c.width = positive_int(path, e, i, "width");
    c.height = positive_int(path, e, i, "height");
    c.fx = positive(path, e, i, "fx");
    c.fy = positive(path, e, i, "fy");
    const JsonValue& pos = member(path, e, i, "position", JsonValue::Type::Array);
    if (pos.items().size() != 3)
      throw InputError(where(path, pos, i) + ": key \"position\" must hold 3 numbers");
    for (int k = 0; k < 3; ++k) c.position[k] = number(path, pos.items()[k], i, "position");
    const JsonValue& rot = member(path, e, i, "rotation", JsonValue::Type::Array);
    if (rot.items().size() != 3)
      throw InputError(where(path, rot, i) + ": key \"rotation\" must hold 3 rows of 3 numbers");
    for (int r = 0; r < 3; ++r) {
      const JsonValue& row = rot.items()[r];
      if (!row.is_array() || row.items().size() != 3)
        throw InputError(where(path, row, i) + ": key \"rotation\" must hold 3 rows of 3 numbers");
      for (int k = 0; k < 3; ++k)
        c.rotation[3 * r + k] = number(path, row.items()[k], i, "rotation");
    }
    // A proper rotation (columns orthonormal, det +1) to the precision cameras.json keeps.
    double worst = 0;
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) {
        double s = 0;
        for (int k = 0; k < 3; ++k) s += c.rotation[3 * k + a] * c.rotation[3 * k + b];
        worst = std::fmax(worst, std::fabs(s - (a == b ? 1.0 : 0.0)));
      }
    const auto& m = c.rotation;
    const double det = m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6]) +
                       m[2] * (m[3] * m[7] - m[4] * m[6]);
    if (!(worst < 1e-4) || !(det > 0))
      throw InputError(where(path, rot, i) +
                       ": key \"rotation\" is not a rotation matrix (orthonormal, det +1)");
    out.push_back(c);
  }
  return out;
}

Camera read_camera_spec(const std::string& spec) {
  std::string path = spec;
  long index = 0;
  const auto colon = spec.rfind(':');
  if (colon != std::string::npos && colon + 1 < spec.size()) {
    const std::string tail = spec.substr(colon + 1);
    if (tail.find_first_not_of("0123456789") == std::string::npos && tail.size() < 10) {
      path = spec.substr(0, colon);
      index = std::stol(tail);
    }
  }
  const auto cams = read_cameras_json(path);
  if (index >= static_cast<long>(cams.size()))
    throw InputError(path + ": camera index " + std::to_string(index) + " is out of range (" +
                     std::to_string(cams.size()) + " entries)");
  return cams[static_cast<std::size_t>(index)];
}

void write_cameras_json(const std::string& path, const std::vector<Camera>& cameras) {
  JsonValue doc = JsonValue::array();
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    const Camera& c = cameras[i];
    JsonValue e = JsonValue::object();
    e.set("id", JsonValue::number(static_cast<double>(i)));
    e.set("img_name", JsonValue::string("view_" + std::to_string(i)));
    e.set("width", JsonValue::number(c.width));
    e.set("height", JsonValue::number(c.height));
    JsonValue pos = JsonValue::array();
    for (double x : c.position) pos.push_back(JsonValue::number(x));
    e.set("position", pos);
    JsonValue rot = JsonValue::array();
    for (int r = 0; r < 3; ++r) {
      JsonValue row = JsonValue::array();
      for (int k = 0; k < 3; ++k) row.push_back(JsonValue::number(c.rotation[3 * r + k]));
      rot.push_back(row);
    }
    e.set("rotation", rot);
    e.set("fy", JsonValue::number(c.fy));
    e.set("fx", JsonValue::number(c.fx));
    doc.push_back(e);
  }
  write_json_file(path, doc, 2);
}

}  // namespace gen4d::gaussians
