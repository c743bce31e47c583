// Recording CSV reader (marker positions and accelerometers; empty cells, NaN, column subsets).
// The first byte picks the reader's options, the rest is the file.
#include <cstddef>
#include <cstdint>

#include "diagnose/Recording.hpp"
#include "fuzz_common.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  gen4d::diagnose::ReadOptions opt;
  if (data[0] & 1) opt.unmeasured.push_back("z");
  if (data[0] & 2) opt.unmeasured.push_back("ax");
  const std::string path = gen4d::fuzz::write_input("recording.csv", data + 1, size - 1);
  gen4d::fuzz::expect_clean_errors([&] {
    const gen4d::diagnose::Recording rec = gen4d::diagnose::read_recording(path, opt);
    (void)rec.samples();
    (void)rec.t_begin();
    (void)rec.t_end();
  });
  return 0;
}
