// Chart rendering to PNG (see Plot.hpp): drawn in software with a built-in bitmap font.
#include "io/Plot.hpp"

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdio>
#include <limits>

#include "core/Error.hpp"
#include "io/PngPreview.hpp"

namespace gen4d::io {
namespace {

// ---------------------------------------------------------------------------------------------
// Bitmap font: 5x9 cells for ASCII 32..126, rows top to bottom, bit 4 the leftmost column.
// Capitals and digits use rows 0-6, descenders rows 7-8. Drawn on a 6-pixel advance.

constexpr int kAdvance = 6;    // glyph width 5 + 1 column of spacing
constexpr int kCapHeight = 7;  // rows above the baseline

const std::uint8_t kFont[95][9] = {
    {0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00},  // space
    {0x04, 0x04, 0x04, 0x04, 0x04, 0x00, 0x04, 0x00, 0x00},  // !
    {0x0A, 0x0A, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00},  // "
    {0x0A, 0x0A, 0x1F, 0x0A, 0x1F, 0x0A, 0x0A, 0x00, 0x00},  // #
    {0x04, 0x0F, 0x14, 0x0E, 0x05, 0x1E, 0x04, 0x00, 0x00},  // $
    {0x18, 0x19, 0x02, 0x04, 0x08, 0x13, 0x03, 0x00, 0x00},  // %
    {0x0C, 0x12, 0x14, 0x08, 0x15, 0x12, 0x0D, 0x00, 0x00},  // &
    {0x04, 0x04, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00},  // '
    {0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02, 0x00, 0x00},  // (
    {0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08, 0x00, 0x00},  // )
    {0x00, 0x04, 0x15, 0x0E, 0x15, 0x04, 0x00, 0x00, 0x00},  // *
    {0x00, 0x04, 0x04, 0x1F, 0x04, 0x04, 0x00, 0x00, 0x00},  // +
    {0x00, 0x00, 0x00, 0x00, 0x00, 0x04, 0x04, 0x08, 0x00},  // ,
    {0x00, 0x00, 0x00, 0x1F, 0x00, 0x00, 0x00, 0x00, 0x00},  // -
    {0x00, 0x00, 0x00, 0x00, 0x00, 0x0C, 0x0C, 0x00, 0x00},  // .
    {0x01, 0x01, 0x02, 0x04, 0x08, 0x10, 0x10, 0x00, 0x00},  // /
    {0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E, 0x00, 0x00},  // 0
    {0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E, 0x00, 0x00},  // 1
    {0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F, 0x00, 0x00},  // 2
    {0x1E, 0x01, 0x01, 0x0E, 0x01, 0x01, 0x1E, 0x00, 0x00},  // 3
    {0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02, 0x00, 0x00},  // 4
    {0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E, 0x00, 0x00},  // 5
    {0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E, 0x00, 0x00},  // 6
    {0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08, 0x00, 0x00},  // 7
    {0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E, 0x00, 0x00},  // 8
    {0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C, 0x00, 0x00},  // 9
    {0x00, 0x0C, 0x0C, 0x00, 0x0C, 0x0C, 0x00, 0x00, 0x00},  // :
    {0x00, 0x0C, 0x0C, 0x00, 0x0C, 0x0C, 0x08, 0x00, 0x00},  // ;
    {0x02, 0x04, 0x08, 0x10, 0x08, 0x04, 0x02, 0x00, 0x00},  // <
    {0x00, 0x00, 0x1F, 0x00, 0x1F, 0x00, 0x00, 0x00, 0x00},  // =
    {0x08, 0x04, 0x02, 0x01, 0x02, 0x04, 0x08, 0x00, 0x00},  // >
    {0x0E, 0x11, 0x01, 0x02, 0x04, 0x00, 0x04, 0x00, 0x00},  // ?
    {0x0E, 0x11, 0x17, 0x15, 0x17, 0x10, 0x0F, 0x00, 0x00},  // @
    {0x0E, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11, 0x00, 0x00},  // A
    {0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E, 0x00, 0x00},  // B
    {0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E, 0x00, 0x00},  // C
    {0x1C, 0x12, 0x11, 0x11, 0x11, 0x12, 0x1C, 0x00, 0x00},  // D
    {0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F, 0x00, 0x00},  // E
    {0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10, 0x00, 0x00},  // F
    {0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F, 0x00, 0x00},  // G
    {0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11, 0x00, 0x00},  // H
    {0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E, 0x00, 0x00},  // I
    {0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C, 0x00, 0x00},  // J
    {0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11, 0x00, 0x00},  // K
    {0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F, 0x00, 0x00},  // L
    {0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11, 0x00, 0x00},  // M
    {0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11, 0x00, 0x00},  // N
    {0x0E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E, 0x00, 0x00},  // O
    {0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10, 0x00, 0x00},  // P
    {0x0E, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0D, 0x00, 0x00},  // Q
    {0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11, 0x00, 0x00},  // R
    {0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E, 0x00, 0x00},  // S
    {0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04, 0x00, 0x00},  // T
    {0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E, 0x00, 0x00},  // U
    {0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04, 0x00, 0x00},  // V
    {0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0A, 0x00, 0x00},  // W
    {0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11, 0x00, 0x00},  // X
    {0x11, 0x11, 0x0A, 0x04, 0x04, 0x04, 0x04, 0x00, 0x00},  // Y
    {0x1F, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1F, 0x00, 0x00},  // Z
    {0x0E, 0x08, 0x08, 0x08, 0x08, 0x08, 0x0E, 0x00, 0x00},  // [
    {0x10, 0x10, 0x08, 0x04, 0x02, 0x01, 0x01, 0x00, 0x00},  // backslash
    {0x0E, 0x02, 0x02, 0x02, 0x02, 0x02, 0x0E, 0x00, 0x00},  // ]
    {0x04, 0x0A, 0x11, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00},  // ^
    {0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x1F, 0x00},  // _
    {0x08, 0x04, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00},  // `
    {0x00, 0x00, 0x0E, 0x01, 0x0F, 0x11, 0x0F, 0x00, 0x00},  // a
    {0x10, 0x10, 0x16, 0x19, 0x11, 0x11, 0x1E, 0x00, 0x00},  // b
    {0x00, 0x00, 0x0E, 0x10, 0x10, 0x11, 0x0E, 0x00, 0x00},  // c
    {0x01, 0x01, 0x0D, 0x13, 0x11, 0x11, 0x0F, 0x00, 0x00},  // d
    {0x00, 0x00, 0x0E, 0x11, 0x1F, 0x10, 0x0E, 0x00, 0x00},  // e
    {0x06, 0x09, 0x08, 0x1C, 0x08, 0x08, 0x08, 0x00, 0x00},  // f
    {0x00, 0x00, 0x0F, 0x11, 0x11, 0x11, 0x0F, 0x01, 0x0E},  // g
    {0x10, 0x10, 0x16, 0x19, 0x11, 0x11, 0x11, 0x00, 0x00},  // h
    {0x04, 0x00, 0x0C, 0x04, 0x04, 0x04, 0x0E, 0x00, 0x00},  // i
    {0x02, 0x00, 0x06, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C},  // j
    {0x10, 0x10, 0x12, 0x14, 0x18, 0x14, 0x12, 0x00, 0x00},  // k
    {0x0C, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E, 0x00, 0x00},  // l
    {0x00, 0x00, 0x1A, 0x15, 0x15, 0x15, 0x15, 0x00, 0x00},  // m
    {0x00, 0x00, 0x16, 0x19, 0x11, 0x11, 0x11, 0x00, 0x00},  // n
    {0x00, 0x00, 0x0E, 0x11, 0x11, 0x11, 0x0E, 0x00, 0x00},  // o
    {0x00, 0x00, 0x1E, 0x11, 0x11, 0x11, 0x1E, 0x10, 0x10},  // p
    {0x00, 0x00, 0x0F, 0x11, 0x11, 0x11, 0x0F, 0x01, 0x01},  // q
    {0x00, 0x00, 0x16, 0x19, 0x10, 0x10, 0x10, 0x00, 0x00},  // r
    {0x00, 0x00, 0x0F, 0x10, 0x0E, 0x01, 0x1E, 0x00, 0x00},  // s
    {0x08, 0x08, 0x1C, 0x08, 0x08, 0x09, 0x06, 0x00, 0x00},  // t
    {0x00, 0x00, 0x11, 0x11, 0x11, 0x13, 0x0D, 0x00, 0x00},  // u
    {0x00, 0x00, 0x11, 0x11, 0x11, 0x0A, 0x04, 0x00, 0x00},  // v
    {0x00, 0x00, 0x11, 0x11, 0x15, 0x15, 0x0A, 0x00, 0x00},  // w
    {0x00, 0x00, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x00, 0x00},  // x
    {0x00, 0x00, 0x11, 0x11, 0x11, 0x11, 0x0F, 0x01, 0x0E},  // y
    {0x00, 0x00, 0x1F, 0x02, 0x04, 0x08, 0x1F, 0x00, 0x00},  // z
    {0x03, 0x04, 0x04, 0x08, 0x04, 0x04, 0x03, 0x00, 0x00},  // {
    {0x04, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04, 0x00, 0x00},  // |
    {0x18, 0x04, 0x04, 0x02, 0x04, 0x04, 0x18, 0x00, 0x00},  // }
    {0x00, 0x00, 0x08, 0x15, 0x02, 0x00, 0x00, 0x00, 0x00},  // ~
};

//! Width in pixels of `text` drawn at integer `scale`.
int text_width(const std::string& text, int scale) {
  return text.empty() ? 0 : static_cast<int>(text.size()) * kAdvance * scale - scale;
}

// ---------------------------------------------------------------------------------------------
// Canvas and anti-aliased coverage.

const Rgb kWhite{255, 255, 255};
const Rgb kInk{30, 30, 30};
const Rgb kAxis{70, 70, 70};
const Rgb kGrid{228, 228, 228};
const Rgb kMinorGrid{242, 242, 242};
const Rgb kBand{255, 222, 160};
const Rgb kNoValue{150, 150, 150};

struct Canvas {
  int width, height;
  std::vector<std::uint8_t> rgb;

  Canvas(int w, int h, Rgb fill) : width(w), height(h), rgb(std::size_t(3) * w * h) {
    for (std::size_t p = 0; p < rgb.size(); p += 3) {
      rgb[p] = fill.r;
      rgb[p + 1] = fill.g;
      rgb[p + 2] = fill.b;
    }
  }

  //! Mixes `color` into pixel (x, y) with weight `alpha`; outside the canvas does nothing.
  void blend(int x, int y, Rgb color, double alpha) {
    if (x < 0 || y < 0 || x >= width || y >= height || alpha <= 0) return;
    std::uint8_t* p = &rgb[3 * (std::size_t(y) * width + x)];
    if (alpha >= 1) {
      p[0] = color.r;
      p[1] = color.g;
      p[2] = color.b;
      return;
    }
    auto mix = [alpha](std::uint8_t a, std::uint8_t b) {
      return static_cast<std::uint8_t>(std::lround(a + (b - a) * alpha));
    };
    p[0] = mix(p[0], color.r);
    p[1] = mix(p[1], color.g);
    p[2] = mix(p[2], color.b);
  }

  //! Fills pixels x0 <= x < x1, y0 <= y < y1.
  void fill(int x0, int y0, int x1, int y1, Rgb color, double alpha = 1) {
    x0 = std::max(x0, 0);
    y0 = std::max(y0, 0);
    x1 = std::min(x1, width);
    y1 = std::min(y1, height);
    for (int y = y0; y < y1; ++y) {
      for (int x = x0; x < x1; ++x) blend(x, y, color, alpha);
    }
  }

  //! One-pixel-wide outline of the pixels x0..x1, y0..y1 (inclusive).
  void outline(int x0, int y0, int x1, int y1, Rgb color, int thickness = 1) {
    for (int t = 0; t < thickness; ++t) {
      fill(x0 + t, y0 + t, x1 + 1 - t, y0 + t + 1, color);
      fill(x0 + t, y1 - t, x1 + 1 - t, y1 - t + 1, color);
      fill(x0 + t, y0 + t, x0 + t + 1, y1 + 1 - t, color);
      fill(x1 - t, y0 + t, x1 - t + 1, y1 + 1 - t, color);
    }
  }

  //! Text with the top of its capitals at row y, starting at column x.
  void text(int x, int y, const std::string& s, int scale, Rgb color) {
    for (std::size_t i = 0; i < s.size(); ++i) {
      int c = static_cast<unsigned char>(s[i]);
      if (c < 32 || c > 126) c = '?';
      const std::uint8_t* glyph = kFont[c - 32];
      const int gx = x + static_cast<int>(i) * kAdvance * scale;
      for (int row = 0; row < 9; ++row) {
        for (int col = 0; col < 5; ++col) {
          if (glyph[row] & (0x10 >> col)) {
            fill(gx + col * scale, y + row * scale, gx + (col + 1) * scale, y + (row + 1) * scale,
                 color);
          }
        }
      }
    }
  }

  //! Copies `cell` with its top-left corner at (x, y).
  void paste(const Canvas& cell, int x, int y) {
    for (int row = 0; row < cell.height && y + row < height; ++row) {
      const int n = std::min(cell.width, width - x);
      std::copy_n(&cell.rgb[3 * std::size_t(row) * cell.width], 3 * n,
                  &rgb[3 * (std::size_t(y + row) * width + x)]);
    }
  }
};

//! Pixel rectangle left..right, top..bottom (inclusive), the clip of what is drawn in it.
struct Area {
  int left = 0, top = 0, right = 0, bottom = 0;
  int width() const { return right - left; }
  int height() const { return bottom - top; }
};

//! Per-pixel coverage of one shape (a polyline, markers) before it is mixed into the canvas
//! in one colour, so overlapping pieces of a line do not darken its joints.
class Coverage {
 public:
  Coverage(int width, int height)
      : width_(width), height_(height), alpha_(std::size_t(width) * height, 0.0f) {}

  //! A disc of radius r centred at (cx, cy), pixel centres at integer + 0.5.
  void disc(double cx, double cy, double r, const Area& clip) {
    if (!std::isfinite(cx) || !std::isfinite(cy)) return;
    const int x0 = std::max(clip.left, int(std::floor(cx - r - 1)));
    const int x1 = std::min(clip.right, int(std::ceil(cx + r + 1)));
    const int y0 = std::max(clip.top, int(std::floor(cy - r - 1)));
    const int y1 = std::min(clip.bottom, int(std::ceil(cy + r + 1)));
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const double d = std::hypot(x + 0.5 - cx, y + 0.5 - cy);
        put(x, y, r + 0.5 - d);
      }
    }
    touch(x0, y0, x1, y1);
  }

  //! A straight stroke of half-width `half` with round ends.
  void segment(double ax, double ay, double bx, double by, double half, const Area& clip) {
    if (!std::isfinite(ax) || !std::isfinite(ay) || !std::isfinite(bx) || !std::isfinite(by)) {
      return;
    }
    if (!clip_segment(ax, ay, bx, by, clip, half + 1)) return;
    // Short pieces keep the scanned boxes tight around diagonal strokes.
    const double length = std::hypot(bx - ax, by - ay);
    const int pieces = std::max(1, int(std::ceil(length / 16.0)));
    for (int k = 0; k < pieces; ++k) {
      const double t0 = double(k) / pieces, t1 = double(k + 1) / pieces;
      piece(ax + (bx - ax) * t0, ay + (by - ay) * t0, ax + (bx - ax) * t1, ay + (by - ay) * t1,
            half, clip);
    }
  }

  //! Mixes the covered pixels into `canvas` in `color` and clears the coverage.
  void flush(Canvas& canvas, Rgb color, double opacity = 1) {
    for (int y = y0_; y <= y1_; ++y) {
      for (int x = x0_; x <= x1_; ++x) {
        float& a = alpha_[std::size_t(y) * width_ + x];
        if (a > 0) canvas.blend(x, y, color, a * opacity);
        a = 0;
      }
    }
    x0_ = y0_ = INT_MAX;
    x1_ = y1_ = INT_MIN;
  }

 private:
  void put(int x, int y, double a) {
    if (a <= 0 || x < 0 || y < 0 || x >= width_ || y >= height_) return;
    float& cell = alpha_[std::size_t(y) * width_ + x];
    cell = std::max(cell, static_cast<float>(std::min(a, 1.0)));
  }

  void touch(int x0, int y0, int x1, int y1) {
    x0_ = std::max(0, std::min(x0_, x0));
    y0_ = std::max(0, std::min(y0_, y0));
    x1_ = std::min(width_ - 1, std::max(x1_, x1));
    y1_ = std::min(height_ - 1, std::max(y1_, y1));
  }

  void piece(double ax, double ay, double bx, double by, double half, const Area& clip) {
    const int x0 = std::max(clip.left, int(std::floor(std::min(ax, bx) - half - 1)));
    const int x1 = std::min(clip.right, int(std::ceil(std::max(ax, bx) + half + 1)));
    const int y0 = std::max(clip.top, int(std::floor(std::min(ay, by) - half - 1)));
    const int y1 = std::min(clip.bottom, int(std::ceil(std::max(ay, by) + half + 1)));
    const double dx = bx - ax, dy = by - ay, len2 = dx * dx + dy * dy;
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const double px = x + 0.5 - ax, py = y + 0.5 - ay;
        const double t = len2 > 0 ? std::clamp((px * dx + py * dy) / len2, 0.0, 1.0) : 0.0;
        put(x, y, half + 0.5 - std::hypot(px - t * dx, py - t * dy));
      }
    }
    touch(x0, y0, x1, y1);
  }

  //! Liang-Barsky: trims the segment to the clip area grown by `margin`; false if outside.
  static bool clip_segment(double& ax, double& ay, double& bx, double& by, const Area& clip,
                           double margin) {
    const double lo[2] = {clip.left - margin, clip.top - margin};
    const double hi[2] = {clip.right + 1 + margin, clip.bottom + 1 + margin};
    const double a[2] = {ax, ay}, d[2] = {bx - ax, by - ay};
    double t0 = 0, t1 = 1;
    for (int k = 0; k < 2; ++k) {
      if (d[k] == 0) {
        if (a[k] < lo[k] || a[k] > hi[k]) return false;
        continue;
      }
      double ta = (lo[k] - a[k]) / d[k], tb = (hi[k] - a[k]) / d[k];
      if (ta > tb) std::swap(ta, tb);
      t0 = std::max(t0, ta);
      t1 = std::min(t1, tb);
      if (t0 > t1) return false;
    }
    bx = a[0] + d[0] * t1;
    by = a[1] + d[1] * t1;
    ax = a[0] + d[0] * t0;
    ay = a[1] + d[1] * t0;
    return true;
  }

  int width_, height_;
  std::vector<float> alpha_;
  int x0_ = INT_MAX, y0_ = INT_MAX, x1_ = INT_MIN, y1_ = INT_MIN;
};

//! Strokes the pixel-space polyline `points` (a run without gaps), dashed if asked; the dash
//! pattern runs on across the vertices.
void stroke(Coverage& cov, const std::vector<std::array<double, 2>>& points, double width,
            bool dashed, const Area& clip) {
  const double half = 0.5 * width;
  double total = 0;
  for (std::size_t i = 1; i < points.size(); ++i) {
    total += std::hypot(points[i][0] - points[i - 1][0], points[i][1] - points[i - 1][1]);
  }
  if (points.empty()) return;
  if (total < 1) {  // a lone point between gaps: a dot that can be seen
    cov.disc(points[0][0], points[0][1], std::max(1.5, width), clip);
    return;
  }
  const double on = 4 * width + 2, off = 2.5 * width + 2;
  double phase = 0;  // distance into the current on+off period
  for (std::size_t i = 1; i < points.size(); ++i) {
    const double ax = points[i - 1][0], ay = points[i - 1][1];
    const double bx = points[i][0], by = points[i][1];
    if (!dashed) {
      cov.segment(ax, ay, bx, by, half, clip);
      continue;
    }
    const double length = std::hypot(bx - ax, by - ay);
    double s = 0;
    while (s < length) {
      const bool drawing = phase < on;
      const double step = std::min(length - s, (drawing ? on : on + off) - phase);
      if (drawing) {
        const double t0 = s / length, t1 = (s + step) / length;
        cov.segment(ax + (bx - ax) * t0, ay + (by - ay) * t0, ax + (bx - ax) * t1,
                    ay + (by - ay) * t1, half, clip);
      }
      s += step;
      phase += step;
      if (phase >= on + off) phase = 0;
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Ranges and ticks.

constexpr double kInf = std::numeric_limits<double>::infinity();

struct Range {
  double lo = kInf, hi = -kInf;
  void add(double v) {
    if (!std::isfinite(v)) return;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  bool empty() const { return !(lo <= hi); }
};

//! [0, 1] when empty; widened around a single value; else grown by `margin` of the span.
Range padded(Range r, double margin) {
  if (r.empty()) return {0, 1};
  const double size = std::max(std::abs(r.lo), std::abs(r.hi));
  if (r.hi - r.lo <= 1e-12 * size || r.hi - r.lo < 1e-300) {
    const double pad = size > 0 ? 0.1 * size : 1.0;
    return {r.lo - pad, r.hi + pad};
  }
  if (!std::isfinite(r.hi - r.lo)) return r;  // spans more than a double holds: as is
  const double m = margin * (r.hi - r.lo);
  return {r.lo - m, r.hi + m};
}

//! Tick positions (in axis space: log10 of the value on a log axis) and their labels.
struct Ticks {
  std::vector<double> at;
  std::vector<std::string> text;
  std::vector<double> minor;  // log axes: 2..9 x 10^k lines
};

//! Label of m x 10^k on a log axis: plain decimals from 0.01 to 9000, else 2e-4 or 1e5.
std::string log_label(int m, int k) {
  if (k >= -2 && k <= 3) return format_tick(m * std::pow(10.0, k), std::pow(10.0, k));
  return std::to_string(m) + "e" + std::to_string(k);
}

Ticks linear_ticks(double lo, double hi, int max_count) {
  Ticks t;
  const std::vector<double> values = nice_ticks(lo, hi, max_count);
  const double step = values.size() > 1 ? values[1] - values[0] : hi - lo;
  for (double v : values) {
    t.at.push_back(v);
    t.text.push_back(format_tick(v, step));
  }
  return t;
}

//! Ticks of an axis spanning [lo, hi], log10 of the values if `log`.
Ticks make_ticks(double lo, double hi, bool log, int max_count) {
  if (!log) return linear_ticks(lo, hi, max_count);
  const int first = int(std::ceil(lo - 1e-9)), last = int(std::floor(hi + 1e-9));
  Ticks t;
  if (last - first + 1 < 2) {  // under two decades shown: plain ticks of the values
    Ticks values = linear_ticks(std::pow(10.0, lo), std::pow(10.0, hi), max_count);
    for (std::size_t i = 0; i < values.at.size(); ++i) {
      if (values.at[i] <= 0) continue;
      t.at.push_back(std::log10(values.at[i]));
      t.text.push_back(values.text[i]);
    }
    return t;
  }
  const int every = (last - first) / std::max(1, max_count) + 1;
  for (int k = first; k <= last; ++k) {
    if (((k % every) + every) % every != 0) continue;
    t.at.push_back(k);
    t.text.push_back(log_label(1, k));
  }
  if (every == 1 && last - first + 1 < 3) {  // few decades: label 2 and 5 x 10^k as well
    std::vector<std::pair<double, std::string>> more;
    for (int k = int(std::floor(lo)); k <= last; ++k) {
      for (int m : {2, 5}) {
        const double v = k + std::log10(double(m));
        if (v > lo && v < hi) more.push_back({v, log_label(m, k)});
      }
    }
    if (t.at.size() + more.size() <= std::size_t(std::max(2, max_count))) {
      for (std::size_t i = 0; i < t.at.size(); ++i) more.push_back({t.at[i], t.text[i]});
      std::sort(more.begin(), more.end());
      t.at.clear();
      t.text.clear();
      for (const auto& [v, text] : more) {
        t.at.push_back(v);
        t.text.push_back(text);
      }
    }
  }
  if (every == 1 && last - first <= 8) {
    for (int k = int(std::floor(lo)); k <= last; ++k) {
      for (int m = 2; m <= 9; ++m) {
        const double v = k + std::log10(double(m));
        if (v > lo && v < hi) t.minor.push_back(v);
      }
    }
  }
  return t;
}

//! Ticks along a horizontal axis of `pixels` length whose labels do not collide.
Ticks fit_x_ticks(double lo, double hi, bool log, int pixels, int scale) {
  Ticks best;
  for (int count = 8; count >= 2; --count) {
    best = make_ticks(lo, hi, log, count);
    int widest = 0;
    for (const std::string& s : best.text) widest = std::max(widest, text_width(s, scale));
    double gap = kInf;
    for (std::size_t i = 1; i < best.at.size(); ++i) {
      gap = std::min(gap, (best.at[i] - best.at[i - 1]) / (hi - lo) * pixels);
    }
    if (gap >= widest + 10 * scale) break;
  }
  return best;
}

Ticks fit_y_ticks(double lo, double hi, bool log, int pixels, int scale) {
  return make_ticks(lo, hi, log, std::clamp(pixels / (24 * scale), 2, 8));
}

// ---------------------------------------------------------------------------------------------
// Plot frame: mapping, grid, axes and labels.

//! A plot area with its axis ranges (log10 of the values on a log axis).
struct Frame {
  Area area;
  double x0 = 0, x1 = 1, y0 = 0, y1 = 1;
  bool log_y = false;
  double px(double x) const { return area.left + 0.5 + (x - x0) / (x1 - x0) * area.width(); }
  double py(double y) const { return area.bottom + 0.5 - (y - y0) / (y1 - y0) * area.height(); }
};

int text_scale(int width, int height) {
  return std::max(1, std::min(width / 800, height / 450));
}

//! Vertical layout shared by the charts: title, the y label above the axis, the plot area and
//! the x tick labels and x label below it. Draws the title and y label.
struct Bands {
  int scale, pad, top, bottom;
};

Bands draw_top(Canvas& c, const std::string& title, const std::string& ylabel,
               const std::string& xlabel, bool label_row) {
  Bands b;
  b.scale = text_scale(c.width, c.height);
  const int s = b.scale, ts = s + 1;
  b.pad = 6 * s;
  int y = b.pad;
  if (!title.empty()) {
    c.text(std::max(0, (c.width - text_width(title, ts)) / 2), y, title, ts, kInk);
    y += 9 * ts + 3 * s;
  }
  if (label_row) {  // the y label, or the colour bar's
    c.text(b.pad, y, ylabel, s, kInk);
    y += 9 * s + 2 * s;
  }
  b.top = y + 4 * s;
  b.bottom = c.height - 1 - b.pad - (xlabel.empty() ? 0 : 9 * s + 4 * s) - 16 * s;
  return b;
}

int widest(const Ticks& t, int scale) {
  int w = 0;
  for (const std::string& s : t.text) w = std::max(w, text_width(s, scale));
  return w;
}

void draw_grid(Canvas& c, const Frame& f, const Ticks& xt, const Ticks& yt) {
  const Area& a = f.area;
  c.fill(a.left, a.top, a.right + 1, a.bottom + 1, kWhite);
  for (double v : yt.minor) {
    const int y = int(std::floor(f.py(v)));
    c.fill(a.left, y, a.right + 1, y + 1, kMinorGrid);
  }
  for (double v : xt.at) {
    const int x = int(std::floor(f.px(v)));
    c.fill(x, a.top, x + 1, a.bottom + 1, kGrid);
  }
  for (double v : yt.at) {
    const int y = int(std::floor(f.py(v)));
    c.fill(a.left, y, a.right + 1, y + 1, kGrid);
  }
}

//! Frame, tick marks, tick labels and the x label under the area.
void draw_axes(Canvas& c, const Frame& f, const Ticks& xt, const Ticks& yt,
               const std::string& xlabel, int s) {
  const Area& a = f.area;
  c.outline(a.left, a.top, a.right, a.bottom, kAxis);
  const int tick = 4 * s;
  for (std::size_t i = 0; i < xt.at.size(); ++i) {
    const int x = int(std::floor(f.px(xt.at[i])));
    c.fill(x, a.bottom + 1, x + 1, a.bottom + 1 + tick, kAxis);
    const int w = text_width(xt.text[i], s);
    const int tx = std::clamp(x - w / 2, 0, c.width - w);
    c.text(tx, a.bottom + 1 + tick + 3 * s, xt.text[i], s, kInk);
  }
  for (std::size_t i = 0; i < yt.at.size(); ++i) {
    const int y = int(std::floor(f.py(yt.at[i])));
    c.fill(a.left - tick, y, a.left, y + 1, kAxis);
    const int w = text_width(yt.text[i], s);
    c.text(a.left - tick - 3 * s - w, y - kCapHeight * s / 2, yt.text[i], s, kInk);
  }
  if (!xlabel.empty()) {
    const int w = text_width(xlabel, s);
    const int x = std::clamp(a.left + (a.width() - w) / 2, 0, std::max(0, c.width - w));
    c.text(x, a.bottom + 1 + tick + 3 * s + 9 * s + 3 * s, xlabel, s, kInk);
  }
}

void draw_centered_note(Canvas& c, const Area& a, const std::string& note, int s) {
  c.text(a.left + (a.width() - text_width(note, s)) / 2, a.top + (a.height() - 7 * s) / 2, note, s,
         kNoValue);
}

// ---------------------------------------------------------------------------------------------
// Line charts.

bool usable(double x, double y, bool log_y) {
  return std::isfinite(x) && std::isfinite(y) && (!log_y || y > 0);
}

//! Pixel-space runs of a series, split at its unusable points.
std::vector<std::vector<std::array<double, 2>>> runs(const Series& s, const Frame& f) {
  std::vector<std::vector<std::array<double, 2>>> out(1);
  const std::size_t n = std::min(s.x.size(), s.y.size());
  for (std::size_t i = 0; i < n; ++i) {
    if (!usable(s.x[i], s.y[i], f.log_y)) {
      if (!out.back().empty()) out.emplace_back();
      continue;
    }
    out.back().push_back({f.px(s.x[i]), f.py(f.log_y ? std::log10(s.y[i]) : s.y[i])});
  }
  if (out.back().empty()) out.pop_back();
  return out;
}

//! Line width and marker radius in pixels; both grow with the text on large charts.
double line_width(const Series& s, int scale) {
  return std::max(0.5, std::isfinite(s.width) ? s.width : 1.5) * scale;
}
double marker_radius(const Series& s, int scale) {
  return std::max(2.0 * scale, line_width(s, scale) + scale);
}

void render_line_chart(Canvas& c, const LineChart& chart) {
  const Bands b = draw_top(c, chart.title, chart.ylabel, chart.xlabel, !chart.ylabel.empty());
  const int s = b.scale;

  Range xr, yr;
  for (const Series& series : chart.series) {
    const std::size_t n = std::min(series.x.size(), series.y.size());
    for (std::size_t i = 0; i < n; ++i) {
      if (!usable(series.x[i], series.y[i], chart.log_y)) continue;
      xr.add(series.x[i]);
      yr.add(chart.log_y ? std::log10(series.y[i]) : series.y[i]);
    }
  }
  const bool no_data = xr.empty();
  Frame f;
  f.log_y = chart.log_y;
  const Range x = padded(xr, 0.02);
  const Range y = padded(yr, 0.05);
  f.x0 = x.lo;
  f.x1 = x.hi;
  f.y0 = y.lo;
  f.y1 = y.hi;
  f.area.top = b.top;
  f.area.bottom = std::max(b.top + 10, b.bottom);
  const Ticks yt = fit_y_ticks(f.y0, f.y1, f.log_y, f.area.height(), s);
  f.area.left = b.pad + widest(yt, s) + 7 * s;
  f.area.right = std::max(f.area.left + 10, c.width - 1 - b.pad - 12 * s);
  const Ticks xt = fit_x_ticks(f.x0, f.x1, false, f.area.width(), s);

  draw_grid(c, f, xt, yt);
  Coverage cov(c.width, c.height);
  for (const auto& band : chart.shaded_x) {
    const double lo = std::min(band.first, band.second), hi = std::max(band.first, band.second);
    if (!(hi >= f.x0 && lo <= f.x1)) continue;  // also drops NaN bounds
    const int px0 = std::max(f.area.left, int(std::floor(f.px(std::max(lo, f.x0)))));
    const int px1 = std::min(f.area.right, int(std::floor(f.px(std::min(hi, f.x1)))));
    c.fill(px0, f.area.top, px1 + 1, f.area.bottom + 1, kBand, 0.45);
  }
  std::vector<std::array<double, 2>> drawn;  // pixel samples of the data, to place the legend
  for (const Series& series : chart.series) {
    for (const auto& run : runs(series, f)) {
      if (series.points) {
        for (const auto& p : run) cov.disc(p[0], p[1], marker_radius(series, s), f.area);
      } else {
        stroke(cov, run, line_width(series, s), series.dashed, f.area);
      }
      for (std::size_t i = 0; i < run.size(); ++i) {
        drawn.push_back(run[i]);
        if (i == 0 || series.points) continue;
        const double len = std::hypot(run[i][0] - run[i - 1][0], run[i][1] - run[i - 1][1]);
        // A segment between points beyond the pixel range has no finite length: no samples.
        const int samples = std::isfinite(len) ? int(std::min(1000.0, len / 4)) : 0;
        for (int k = 1; k < samples; ++k) {
          const double t = double(k) / samples;
          drawn.push_back({run[i - 1][0] + t * (run[i][0] - run[i - 1][0]),
                           run[i - 1][1] + t * (run[i][1] - run[i - 1][1])});
        }
      }
    }
    cov.flush(c, series.color);
  }
  draw_axes(c, f, xt, yt, chart.xlabel, s);
  if (no_data) draw_centered_note(c, f.area, "no data", s);

  // Legend in the corner that hides the fewest data samples.
  std::vector<const Series*> listed;
  int label_w = 0;
  for (const Series& series : chart.series) {
    if (series.label.empty()) continue;
    listed.push_back(&series);
    label_w = std::max(label_w, text_width(series.label, s));
  }
  if (listed.empty()) return;
  const int row = 11 * s, sample = 18 * s;
  const int box_w = 6 * s + sample + 5 * s + label_w + 6 * s;
  const int box_h = 5 * s + int(listed.size()) * row + 2 * s;
  const int inset = 6 * s;
  const Area& a = f.area;
  const std::array<std::array<int, 2>, 4> corners = {
      {{a.right - inset - box_w, a.top + inset},
       {a.left + inset, a.top + inset},
       {a.right - inset - box_w, a.bottom - inset - box_h},
       {a.left + inset, a.bottom - inset - box_h}}};
  std::size_t best = 0, best_hits = SIZE_MAX;
  for (std::size_t k = 0; k < corners.size(); ++k) {
    std::size_t hits = 0;
    for (const auto& p : drawn) {
      hits += p[0] >= corners[k][0] - 2 && p[0] <= corners[k][0] + box_w + 2 &&
              p[1] >= corners[k][1] - 2 && p[1] <= corners[k][1] + box_h + 2;
    }
    if (hits < best_hits) {
      best = k;
      best_hits = hits;
    }
  }
  const int bx = corners[best][0], by = corners[best][1];
  c.fill(bx, by, bx + box_w + 1, by + box_h + 1, kWhite, 0.88);
  c.outline(bx, by, bx + box_w, by + box_h, Rgb{190, 190, 190});
  const Area legend{bx, by, bx + box_w, by + box_h};
  for (std::size_t i = 0; i < listed.size(); ++i) {
    const Series& series = *listed[i];
    const int ty = by + 5 * s + int(i) * row;
    const double cy = ty + 3.5 * s;
    const double x0 = bx + 6 * s, x1 = x0 + sample;
    if (series.points) {
      cov.disc(0.5 * (x0 + x1), cy, marker_radius(series, s), legend);
    } else {
      stroke(cov, {{x0, cy}, {x1, cy}}, line_width(series, s), series.dashed, legend);
    }
    cov.flush(c, series.color);
    c.text(int(x1) + 5 * s, ty, series.label, s, kInk);
  }
}

// ---------------------------------------------------------------------------------------------
// Scatter maps.

//! Hand-picked points along a perceptually ordered dark-purple, blue, teal, green, yellow ramp.
const std::array<Rgb, 9> kRamp = {{{68, 1, 84},
                                   {72, 40, 120},
                                   {62, 74, 137},
                                   {49, 104, 142},
                                   {38, 130, 142},
                                   {31, 158, 137},
                                   {53, 183, 121},
                                   {110, 206, 88},
                                   {253, 231, 37}}};

//! The scale limits of a map: its own when given, else from its finite values.
Range value_range(const ScatterMap& m) {
  Range r;
  if (m.vmax >= m.vmin && std::isfinite(m.vmin) && std::isfinite(m.vmax)) {
    r.add(m.vmin);
    r.add(m.vmax);
  } else {
    for (double v : m.value) r.add(v);
  }
  return padded(r, 0.0);
}

void render_scatter_map(Canvas& c, const ScatterMap& map) {
  const Bands b = draw_top(c, map.title, map.ylabel, map.xlabel,
                           !map.ylabel.empty() || !map.colorbar_label.empty());
  const int s = b.scale;
  const Range vr = value_range(map);

  // Colour bar column on the right: bar, ticks, labels; its label above it.
  const int bar_w = 12 * s;
  const int area_top = b.top, area_bottom = std::max(b.top + 10, b.bottom);
  const Ticks ct = fit_y_ticks(vr.lo, vr.hi, false, area_bottom - area_top, s);
  const int bar_right = c.width - 1 - b.pad - widest(ct, s) - 7 * s;
  const int bar_left = bar_right - bar_w;

  Frame f;
  f.area.top = area_top;
  f.area.bottom = area_bottom;
  Range xr, yr;
  const std::size_t n = std::min(map.x.size(), map.y.size());
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(map.x[i]) || !std::isfinite(map.y[i])) continue;
    xr.add(map.x[i]);
    yr.add(map.y[i]);
  }
  for (const auto& r : map.rects) {
    xr.add(r[0]);
    xr.add(r[2]);
    yr.add(r[1]);
    yr.add(r[3]);
  }
  const bool no_data = xr.empty();
  Range x = padded(xr, 0.06), y = padded(yr, 0.06);
  // The y tick labels set the left edge; estimate them on the unadjusted range first.
  Ticks yt = fit_y_ticks(y.lo, y.hi, false, f.area.height(), s);
  f.area.left = b.pad + widest(yt, s) + 7 * s;
  f.area.right = std::max(f.area.left + 10, bar_left - 14 * s);
  if (map.equal_aspect) {
    const double per_pixel =
        std::max((x.hi - x.lo) / f.area.width(), (y.hi - y.lo) / f.area.height());
    const double cx = 0.5 * (x.lo + x.hi), cy = 0.5 * (y.lo + y.hi);
    x = {cx - 0.5 * per_pixel * f.area.width(), cx + 0.5 * per_pixel * f.area.width()};
    y = {cy - 0.5 * per_pixel * f.area.height(), cy + 0.5 * per_pixel * f.area.height()};
    yt = fit_y_ticks(y.lo, y.hi, false, f.area.height(), s);
  }
  f.x0 = x.lo;
  f.x1 = x.hi;
  f.y0 = y.lo;
  f.y1 = y.hi;
  const Ticks xt = fit_x_ticks(f.x0, f.x1, false, f.area.width(), s);

  draw_grid(c, f, xt, yt);
  Coverage cov(c.width, c.height);
  for (std::size_t k = 0; k < map.rects.size(); ++k) {
    const auto& r = map.rects[k];
    const double x0 = f.px(r[0]), y0 = f.py(r[1]), x1 = f.px(r[2]), y1 = f.py(r[3]);
    stroke(cov, {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}, {x0, y0}}, 1.5, false, f.area);
    cov.flush(c, k < map.rect_colors.size() ? map.rect_colors[k] : Rgb{90, 90, 90});
  }

  // Points, smallest values first so the largest stay on top.
  std::vector<std::size_t> order;
  for (std::size_t i = 0; i < n; ++i) {
    if (std::isfinite(map.x[i]) && std::isfinite(map.y[i])) order.push_back(i);
  }
  auto value_at = [&](std::size_t i) {
    return i < map.value.size() && std::isfinite(map.value[i]) ? map.value[i] : -kInf;
  };
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t p, std::size_t q) { return value_at(p) < value_at(q); });
  const double r = 4.5 * s;
  for (std::size_t i : order) {
    const double px = f.px(map.x[i]), py = f.py(map.y[i]);
    const double v = value_at(i);
    cov.disc(px, py, r + 1.2, f.area);
    cov.flush(c, v == -kInf ? kNoValue : Rgb{40, 40, 40});
    cov.disc(px, py, r, f.area);
    cov.flush(c, v == -kInf ? kWhite : colormap((v - vr.lo) / (vr.hi - vr.lo)));
  }
  // Labels right of their point, else left of it, skipped where they would overlap.
  std::vector<Area> taken;
  for (std::size_t k = order.size(); k-- > 0;) {
    const std::size_t i = order[k];
    if (i >= map.labels.size() || map.labels[i].empty()) continue;
    const int px = int(f.px(map.x[i])), py = int(f.py(map.y[i]));
    const int w = text_width(map.labels[i], s), h = 9 * s;
    for (int side : {1, -1}) {
      const int tx = side > 0 ? px + int(r) + 3 * s : px - int(r) - 3 * s - w;
      const Area box{tx - s, py - 4 * s - s, tx + w + s, py - 4 * s + h};
      if (box.left < f.area.left || box.right > f.area.right || box.top < f.area.top ||
          box.bottom > f.area.bottom) {
        continue;
      }
      bool clash = false;
      for (const Area& t : taken) {
        clash = clash || !(box.right < t.left || box.left > t.right || box.bottom < t.top ||
                           box.top > t.bottom);
      }
      if (clash) continue;
      taken.push_back(box);
      c.text(tx, py - 4 * s, map.labels[i], s, Rgb{60, 60, 60});
      break;
    }
  }
  draw_axes(c, f, xt, yt, map.xlabel, s);
  if (no_data) draw_centered_note(c, f.area, "no data", s);

  // Colour bar.
  const int h = f.area.height();
  for (int yy = f.area.top; yy <= f.area.bottom; ++yy) {
    const double t = h > 0 ? double(f.area.bottom - yy) / h : 0.0;
    c.fill(bar_left, yy, bar_right + 1, yy + 1, colormap(t));
  }
  c.outline(bar_left, f.area.top, bar_right, f.area.bottom, kAxis);
  for (std::size_t i = 0; i < ct.at.size(); ++i) {
    const int yy = int(std::floor(f.area.bottom + 0.5 - (ct.at[i] - vr.lo) / (vr.hi - vr.lo) * h));
    c.fill(bar_right + 1, yy, bar_right + 1 + 3 * s, yy + 1, kAxis);
    c.text(bar_right + 4 * s + 2 * s, yy - kCapHeight * s / 2, ct.text[i], s, kInk);
  }
  if (!map.colorbar_label.empty()) {
    const int w = text_width(map.colorbar_label, s);
    const int tx = std::clamp(bar_left + bar_w / 2 - w / 2, 0, std::max(0, c.width - b.pad - w));
    c.text(tx, f.area.top - 4 * s - 11 * s, map.colorbar_label, s, kInk);
  }
}

// ---------------------------------------------------------------------------------------------
// Grids of cells and checks.

void check_layout(const std::string& path, std::size_t count, int cols, int cell_w, int cell_h) {
  auto fail = [&](const std::string& why) { throw InputError("plot " + path + ": " + why); };
  if (count == 0) fail("nothing to draw");
  if (cols < 1) fail("columns must be at least 1, got " + std::to_string(cols));
  if (cell_w < 160 || cell_w > 8192 || cell_h < 120 || cell_h > 8192) {
    fail("chart size " + std::to_string(cell_w) + "x" + std::to_string(cell_h) +
         " outside 160..8192 x 120..8192 pixels");
  }
  const long used = std::min<long>(cols, long(count));
  const long rows = (long(count) + used - 1) / used;
  if (used * cell_w > 16384 || rows * cell_h > 16384 ||
      used * cell_w * rows * cell_h > (1L << 26)) {
    fail("image of " + std::to_string(used * cell_w) + "x" + std::to_string(rows * cell_h) +
         " pixels is too large (16384 per side, 2^26 in all)");
  }
}

template <class Item, class Render>
void write_grid(const std::string& path, const std::vector<Item>& items, int cols, int cell_w,
                int cell_h, Render render) {
  check_layout(path, items.size(), cols, cell_w, cell_h);
  const int used = std::min<int>(cols, int(items.size()));
  const int rows = (int(items.size()) + used - 1) / used;
  Canvas image(used * cell_w, rows * cell_h, kWhite);
  for (std::size_t k = 0; k < items.size(); ++k) {
    Canvas cell(cell_w, cell_h, kWhite);
    render(cell, items[k]);
    image.paste(cell, int(k % used) * cell_w, int(k / used) * cell_h);
  }
  write_png_rgb(path, image.width, image.height, image.rgb);
}

}  // namespace

Rgb palette_color(int index) {
  static const std::array<Rgb, 8> colors = {{{0, 114, 178},
                                             {213, 94, 0},
                                             {0, 158, 115},
                                             {204, 121, 167},
                                             {230, 159, 0},
                                             {86, 180, 233},
                                             {90, 90, 90},
                                             {150, 30, 40}}};
  const int n = int(colors.size());
  return colors[((index % n) + n) % n];
}

Rgb colormap(double t) {
  if (!std::isfinite(t)) t = 0;
  t = std::clamp(t, 0.0, 1.0) * (kRamp.size() - 1);
  const std::size_t i = std::min(kRamp.size() - 2, std::size_t(t));
  const double u = t - double(i);
  auto mix = [u](std::uint8_t a, std::uint8_t b) {
    return static_cast<std::uint8_t>(std::lround(a + (b - a) * u));
  };
  return {mix(kRamp[i].r, kRamp[i + 1].r), mix(kRamp[i].g, kRamp[i + 1].g),
          mix(kRamp[i].b, kRamp[i + 1].b)};
}

std::vector<double> nice_ticks(double lo, double hi, int max_count) {
  if (!std::isfinite(lo) || !std::isfinite(hi) || !(lo < hi) || !std::isfinite(hi - lo) ||
      hi - lo < 1e-290) {
    return {};
  }
  max_count = std::max(max_count, 1);
  int k = int(std::floor(std::log10((hi - lo) / max_count))) - 1;
  for (;; ++k) {
    for (double m : {1.0, 2.0, 5.0}) {
      // step = m * 10^k, kept as m / 10^-k for negative k so decimal steps stay exact.
      const double scale = std::pow(10.0, std::abs(k));
      const double step = k >= 0 ? m * scale : m / scale;
      const double first = std::ceil(lo / step - 1e-9), last = std::floor(hi / step + 1e-9);
      if (!std::isfinite(last - first) || last - first + 1 > max_count) continue;
      std::vector<double> ticks;
      for (double i = first; i <= last; ++i)
        ticks.push_back(k >= 0 ? i * m * scale : i * m / scale);
      return ticks;
    }
  }
}

std::string format_tick(double value, double step) {
  if (!std::isfinite(value)) return std::isnan(value) ? "nan" : (value > 0 ? "inf" : "-inf");
  step = std::abs(step);
  if (!(step > 0) || !std::isfinite(step)) step = value != 0 ? std::abs(value) : 1.0;
  if (std::abs(value) < step * 1e-6) return "0";
  const int step_exp = int(std::floor(std::log10(step) + 1e-9));
  char buf[64];
  if (step_exp <= -4 || step_exp >= 5) {
    int e = int(std::floor(std::log10(std::abs(value)) + 1e-9));
    const int digits = std::clamp(e - step_exp, 0, 6);
    std::snprintf(buf, sizeof buf, "%.*f", digits, value / std::pow(10.0, e));
    if (std::abs(std::atof(buf)) >= 10) {  // 9.99 rounded up to 10.0
      ++e;
      std::snprintf(buf, sizeof buf, "%.*f", std::max(0, digits - 1), value / std::pow(10.0, e));
    }
    std::string mantissa = buf;
    if (mantissa.find('.') != std::string::npos) {
      while (mantissa.back() == '0') mantissa.pop_back();
      if (mantissa.back() == '.') mantissa.pop_back();
    }
    return mantissa + "e" + std::to_string(e);
  }
  int decimals = std::max(0, -step_exp);
  while (decimals < 10) {
    const double scaled = step * std::pow(10.0, decimals);
    if (std::abs(scaled - std::round(scaled)) < 1e-6 * scaled) break;
    ++decimals;
  }
  std::snprintf(buf, sizeof buf, "%.*f", decimals, value);
  return buf;
}

void write_line_chart(const std::string& path, const LineChart& chart, int width, int height) {
  write_chart_grid(path, {chart}, 1, width, height);
}

void write_chart_grid(const std::string& path, const std::vector<LineChart>& charts, int cols,
                      int cell_w, int cell_h) {
  write_grid(path, charts, cols, cell_w, cell_h, render_line_chart);
}

void write_scatter_maps(const std::string& path, const std::vector<ScatterMap>& maps, int cols,
                        int cell_w, int cell_h) {
  write_grid(path, maps, cols, cell_w, cell_h, render_scatter_map);
}

void share_color_scale(std::vector<ScatterMap>& maps) {
  Range r;
  for (const ScatterMap& m : maps) {
    for (double v : m.value) r.add(v);
  }
  if (r.empty()) return;
  for (ScatterMap& m : maps) {
    m.vmin = r.lo;
    m.vmax = r.hi;
  }
}

}  // namespace gen4d::io
