// The deck reader: TOML text, then --set overrides. The input is the deck text up to the first
// NUL byte; each further NUL-separated piece is one "key=value" override, applied in order.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "core/Deck.hpp"
#include "fuzz_common.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string input(reinterpret_cast<const char*>(data), size);
  std::size_t end = input.find('\0');
  const std::string text = input.substr(0, end);
  std::vector<std::string> overrides;
  while (end != std::string::npos) {
    const std::size_t next = input.find('\0', end + 1);
    overrides.push_back(input.substr(end + 1, next == std::string::npos ? next : next - end - 1));
    end = next;
  }
  const std::string path = gen4d::fuzz::write_input("deck.toml", data, text.size());
  gen4d::fuzz::expect_clean_errors([&] {
    const gen4d::Config cfg = gen4d::load_deck(path, overrides);
    // A deck that was read must read again from its own text (how restarts recover it).
    const gen4d::Config again = gen4d::parse_deck(cfg.text, "<restart>", "", {});
    (void)again;
  });
  return 0;
}
