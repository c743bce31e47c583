//! Reads a PNG back for the preview tests (libpng's simplified API).
#pragma once

#include <png.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace gen4d::test {

struct Picture {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;
  std::array<std::uint8_t, 3> at(int x, int y) const {
    const std::size_t p = 3 * (std::size_t(y) * width + x);
    return {rgb[p], rgb[p + 1], rgb[p + 2]};
  }
};

//! The image as RGB; width 0 when the file cannot be read.
inline Picture load_png(const std::string& path) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  Picture picture;
  if (!png_image_begin_read_from_file(&image, path.c_str())) return picture;
  image.format = PNG_FORMAT_RGB;
  picture.rgb.resize(PNG_IMAGE_SIZE(image));
  if (png_image_finish_read(&image, nullptr, picture.rgb.data(), 0, nullptr)) {
    picture.width = static_cast<int>(image.width);
    picture.height = static_cast<int>(image.height);
  }
  return picture;
}

}  // namespace gen4d::test
