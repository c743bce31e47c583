// OpenVDB level sets read from a corrupted .vdb file (header, grid descriptors, trees).
#include <cstddef>
#include <cstdint>

#include "fuzz_common.hpp"
#include "geometry/Shape.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = gen4d::fuzz::write_input("input.vdb", data, size);
  gen4d::fuzz::expect_clean_errors([&] {
    gen4d::geometry::VdbLevelSet level_set(path, "", 1.0, Eigen::Vector3d::Zero());
    (void)level_set.signed_distance(Eigen::Vector3d::Zero());
  });
  return 0;
}
