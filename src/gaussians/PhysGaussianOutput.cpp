#include "gaussians/PhysGaussianOutput.hpp"

#include <fmt/format.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>

#include "core/Error.hpp"

namespace gen4d::gaussians {

namespace fs = std::filesystem;

std::vector<Camera> cameras_to_simulation(const std::vector<Camera>& cameras,
                                          const PhysGaussianSimMap& map) {
  std::vector<Camera> out = cameras;
  for (Camera& c : out) {
    c.position = map.to_sim(c.position);
    std::array<double, 9> r{};
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        for (int k = 0; k < 3; ++k) r[3 * i + j] += map.rotation[3 * i + k] * c.rotation[3 * k + j];
    c.rotation = r;
  }
  return out;
}

std::string simulation_ply_name(long frame) {
  return (fs::path("simulation_ply") / fmt::format("sim_{:010d}.ply", frame)).string();
}

void write_positions_ply(const std::string& path, const std::vector<double>& xyz) {
  if (xyz.size() % 3 != 0)
    throw std::logic_error("write_positions_ply: the coordinates are not triples");
  const std::size_t n = xyz.size() / 3;
  std::string body(4 * xyz.size(), '\0');
  for (std::size_t i = 0; i < xyz.size(); ++i) {
    const float v = static_cast<float>(xyz[i]);
    std::memcpy(&body[4 * i], &v, 4);
  }
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out << "ply\nformat binary_little_endian 1.0\nelement vertex " << n
        << "\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
    out.write(body.data(), static_cast<std::streamsize>(body.size()));
    if (!out) {
      std::error_code ec;
      fs::remove(tmp, ec);
      throw RuntimeError(path + ": cannot write the particle PLY");
    }
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw RuntimeError(path + ": cannot rename the particle PLY into place: " + ec.message());
  }
}

std::vector<float> read_positions_ply(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot open the particle PLY");
  auto fail = [&](const std::string& what) { throw InputError(path + ": " + what); };
  std::string line;
  std::vector<std::string> header;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    header.push_back(line);
    if (line == "end_header" || header.size() > 64) break;
  }
  const std::vector<std::string> fixed = {"ply",
                                          "format binary_little_endian 1.0",
                                          "",
                                          "property float x",
                                          "property float y",
                                          "property float z",
                                          "end_header"};
  if (header.size() != fixed.size()) fail("not a PLY of float x, y, z points (header)");
  long long n = -1;
  for (std::size_t i = 0; i < fixed.size(); ++i) {
    if (i == 2) {
      std::istringstream words(header[i]);
      std::string element, vertex, rest;
      if (!(words >> element >> vertex >> n) || element != "element" || vertex != "vertex" ||
          n < 0 || (words >> rest))
        fail("header line 3: expected 'element vertex N'");
    } else if (header[i] != fixed[i]) {
      fail(fmt::format("header line {}: expected '{}'", i + 1, fixed[i]));
    }
  }
  const std::string body((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (body.size() != 12 * static_cast<std::size_t>(n))
    fail(fmt::format("{} vertices need {} bytes after the header, the file has {}", n, 12 * n,
                     body.size()));
  std::vector<float> xyz(3 * static_cast<std::size_t>(n));
  if (!xyz.empty()) std::memcpy(xyz.data(), body.data(), body.size());
  return xyz;
}

}  // namespace gen4d::gaussians
