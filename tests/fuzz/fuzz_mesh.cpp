// OBJ and STL (ASCII and binary) readers. The first byte picks the format, the rest is the file.
#include <cstddef>
#include <cstdint>

#include "fuzz_common.hpp"
#include "geometry/Mesh.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const bool obj = (data[0] & 1) == 0;
  const std::string path =
      gen4d::fuzz::write_input(obj ? "input.obj" : "input.stl", data + 1, size - 1);
  gen4d::fuzz::expect_clean_errors([&] {
    const gen4d::geometry::Mesh mesh = gen4d::geometry::read_mesh(path);
    (void)mesh;
  });
  return 0;
}
