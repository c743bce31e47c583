//! Small self-contained chart renderer writing PNGs: line charts (linear or log y) and
//! coloured scatter maps, with a built-in bitmap font, so diagnostics need no plotting tool.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace gen4d::io {

struct Rgb {
  std::uint8_t r = 0, g = 0, b = 0;
};

//! A few distinct, colour-blind friendly line colours; index wraps around.
Rgb palette_color(int index);

//! One curve. Non-finite x or y (and, on a log axis, y <= 0) leave a gap in the line.
struct Series {
  std::string label;  // empty: not listed in the legend
  std::vector<double> x, y;
  Rgb color;
  bool points = false;  // filled markers instead of a line
  double width = 1.5;   // line width in pixels, times the text scale on charts of 1600x900 and up;
                        // markers: radius width + 1
  bool dashed = false;
};

struct LineChart {
  std::string title, xlabel, ylabel;
  std::vector<Series> series;
  bool log_y = false;
  std::vector<std::pair<double, double>> shaded_x;  // x intervals drawn as a light band
};

//! Renders one chart to a width x height PNG at `path` (written under a temporary name, then
//! renamed). Sizes outside 160..8192 x 120..8192 are InputErrors, write failures
//! RuntimeErrors; both name the path.
void write_line_chart(const std::string& path, const LineChart& chart, int width = 900,
                      int height = 500);

//! Several charts in one PNG, `cols` per row, row by row, each in a cell_w x cell_h cell.
void write_chart_grid(const std::string& path, const std::vector<LineChart>& charts, int cols,
                      int cell_w, int cell_h);

//! Values at 2-D points coloured on a viridis-like scale, with a colour bar.
struct ScatterMap {
  std::string title, xlabel, ylabel, colorbar_label;
  std::vector<double> x, y, value;  // non-finite value: drawn as a hollow grey marker
  std::vector<std::string> labels;  // optional text next to each point (skipped where crowded)
  double vmin = 0, vmax = -1;       // vmax < vmin: from the finite values
  std::vector<std::array<double, 4>> rects;  // outlines (x0, y0, x1, y1)
  std::vector<Rgb> rect_colors;              // per rect; dark grey where missing
  bool equal_aspect = true;                  // same scale on both axes (a projection)
};

//! Several maps in one PNG, `cols` per row, each in a cell_w x cell_h cell. Every map has its
//! own colour scale; share_color_scale makes them one.
void write_scatter_maps(const std::string& path, const std::vector<ScatterMap>& maps, int cols,
                        int cell_w, int cell_h);

//! Sets every map's vmin/vmax to the range of the finite values of all of them.
void share_color_scale(std::vector<ScatterMap>& maps);

//! The colour scale at t in [0, 1] (clamped): dark purple through teal to yellow.
Rgb colormap(double t);

//! "Nice" tick values (1, 2 or 5 x 10^k steps) inside [lo, hi], at most max_count of them
//! (at least 2 where the range allows).
std::vector<double> nice_ticks(double lo, double hi, int max_count = 8);

//! Compact tick label: 0, 0.5, 12, 1e-3, 2.5e-4, 3e5; `step` is the tick spacing.
std::string format_tick(double value, double step);

}  // namespace gen4d::io
