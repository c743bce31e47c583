// PhysGaussian JSON configs: the JSON parser and the config reader on top of it.
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_common.hpp"
#include "gaussians/Json.hpp"
#include "gaussians/PhysGaussianConfig.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  gen4d::fuzz::expect_clean_errors([&] {
    const gen4d::gaussians::JsonValue value = gen4d::gaussians::parse_json(text, "<fuzz>");
    (void)value.dump(2);
  });
  const std::string path = gen4d::fuzz::write_input("config.json", data, size);
  gen4d::fuzz::expect_clean_errors([&] {
    const gen4d::gaussians::PhysGaussianParams params =
        gen4d::gaussians::read_physgaussian_config(path);
    (void)gen4d::gaussians::physgaussian_rotation(params);
  });
  return 0;
}
