// 3DGS PLY reader (binary little-endian and ASCII bodies).
#include <cstddef>
#include <cstdint>

#include "fuzz_common.hpp"
#include "gaussians/Ply.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = gen4d::fuzz::write_input("input.ply", data, size);
  gen4d::fuzz::expect_clean_errors([&] {
    const gen4d::gaussians::SplatSet splats = gen4d::gaussians::read_splats_ply(path);
    (void)splats;
  });
  return 0;
}
