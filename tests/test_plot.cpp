// Chart PNGs: requested sizes, data drawn where it belongs, text, colour scale, edge cases and
// clean failures. GEN4D_PLOT_DEMO=<dir> also writes a few sample charts there to look at.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <limits>

#include "core/Error.hpp"
#include "io/Plot.hpp"
#include "png_test_util.hpp"
#include "test_io_support.hpp"

namespace gen4d::io {
namespace {

using test::load_png;
using test::Picture;

const Rgb kRed{220, 20, 30};
const Rgb kBlue{20, 40, 220};
const double kNaN = std::numeric_limits<double>::quiet_NaN();

bool is(const std::array<std::uint8_t, 3>& p, Rgb c) {
  return p[0] == c.r && p[1] == c.g && p[2] == c.b;
}

//! Bounding box and mean position of the pixels of exactly colour c.
struct Spot {
  int count = 0, x0 = 1 << 30, y0 = 1 << 30, x1 = -1, y1 = -1;
  double mx = 0, my = 0;
};
Spot find(const Picture& p, Rgb c, int y_from = 0, int y_to = -1) {
  Spot s;
  if (y_to < 0) y_to = p.height;
  for (int y = y_from; y < y_to; ++y) {
    for (int x = 0; x < p.width; ++x) {
      if (!is(p.at(x, y), c)) continue;
      ++s.count;
      s.x0 = std::min(s.x0, x);
      s.x1 = std::max(s.x1, x);
      s.y0 = std::min(s.y0, y);
      s.y1 = std::max(s.y1, y);
      s.mx += x;
      s.my += y;
    }
  }
  if (s.count) {
    s.mx /= s.count;
    s.my /= s.count;
  }
  return s;
}

int dark_pixels(const Picture& p, int y0, int y1) {
  int n = 0;
  for (int y = y0; y < y1; ++y) {
    for (int x = 0; x < p.width; ++x) {
      const auto c = p.at(x, y);
      n += c[0] < 100 && c[1] < 100 && c[2] < 100;
    }
  }
  return n;
}

//! A red horizontal line y = 0.5 and blue markers at (0, 0) and (1, 1).
LineChart line_and_corners() {
  LineChart chart;
  chart.title = "Residual";
  chart.xlabel = "time [s]";
  chart.ylabel = "value";
  chart.series.push_back({"line", {0, 0.5, 1}, {0.5, 0.5, 0.5}, kRed, false, 2.0, false});
  chart.series.push_back({"corners", {0, 1}, {0, 1}, kBlue, true, 2.0, false});
  return chart;
}

TEST(Plot, LineChartSizeAndPlacement) {
  const std::string path = iotest::scratch_dir("plot_line") + "/line.png";
  LineChart chart = line_and_corners();
  for (Series& s : chart.series) s.label.clear();  // no legend
  write_line_chart(path, chart, 640, 400);
  const Picture p = load_png(path);
  ASSERT_EQ(p.width, 640);
  ASSERT_EQ(p.height, 400);
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));

  // The markers sit at the ends of the data range, the line halfway between them in y and
  // across them in x.
  const Spot blue_low = find(p, kBlue, p.height / 2, p.height);
  const Spot blue_high = find(p, kBlue, 0, p.height / 2);
  ASSERT_GT(blue_low.count, 5);
  ASSERT_GT(blue_high.count, 5);
  const double low_y = blue_low.y1 - 0.5 * (blue_low.y1 - blue_low.y0);
  const double high_y = blue_high.y0 + 0.5 * (blue_high.y1 - blue_high.y0);
  EXPECT_LT(high_y, low_y - 200);

  // Red rows: the line's own rows hold most red pixels.
  std::vector<int> per_row(p.height, 0);
  for (int y = 0; y < p.height; ++y) {
    for (int x = 0; x < p.width; ++x) per_row[y] += is(p.at(x, y), kRed);
  }
  const int line_row = int(std::max_element(per_row.begin(), per_row.end()) - per_row.begin());
  EXPECT_NEAR(line_row, 0.5 * (low_y + high_y), 2.0);
  EXPECT_GT(per_row[line_row], 400);  // spans most of the width
  int left = p.width, right = 0;
  for (int x = 0; x < p.width; ++x) {
    if (is(p.at(x, line_row), kRed)) {
      left = std::min(left, x);
      right = std::max(right, x);
    }
  }
  const Spot blue_left = find(p, kBlue, int(low_y) - 8, int(low_y) + 8);
  EXPECT_NEAR(left, blue_left.mx, 3.0);

  // Title text in the top band; nothing dark in the corner of the margin.
  EXPECT_GT(dark_pixels(p, 0, 22), 30);
  EXPECT_TRUE(is(p.at(0, 0), Rgb{255, 255, 255}));
}

TEST(Plot, TitleIsText) {
  const std::string dir = iotest::scratch_dir("plot_title");
  LineChart with = line_and_corners(), without = line_and_corners();
  without.title.clear();
  write_line_chart(dir + "/with.png", with, 500, 300);
  write_line_chart(dir + "/without.png", without, 500, 300);
  const Picture a = load_png(dir + "/with.png"), b = load_png(dir + "/without.png");
  EXPECT_GT(dark_pixels(a, 0, 20), 40);
  EXPECT_EQ(dark_pixels(b, 0, 6), 0);
}

TEST(Plot, EdgeCasesDoNotCrash) {
  const std::string dir = iotest::scratch_dir("plot_edges");
  LineChart chart;
  chart.title = "edge cases";
  chart.log_y = true;
  chart.series.push_back({"nan", {0, 1, 2, 3, 4}, {1, kNaN, 3, 0, -1}, kRed});
  chart.series.push_back({"empty", {}, {}, kBlue});
  chart.series.push_back({"mismatched", {0, 1, 2}, {5}, kBlue, true});
  chart.shaded_x = {{1, 2}, {kNaN, 3}, {-100, 100}};
  write_line_chart(dir + "/log.png", chart, 400, 300);
  EXPECT_EQ(load_png(dir + "/log.png").width, 400);

  LineChart flat;  // all equal values, and nothing usable on a log axis
  flat.series.push_back({"", {2, 2, 2}, {7, 7, 7}, kRed});
  write_line_chart(dir + "/flat.png", flat, 300, 200);
  EXPECT_EQ(load_png(dir + "/flat.png").height, 200);
  flat.log_y = true;
  flat.series[0].y = {0, -1, kNaN};
  write_line_chart(dir + "/nothing.png", flat, 300, 200);
  write_line_chart(dir + "/blank.png", LineChart{}, 300, 200);
  LineChart extreme;
  extreme.series.push_back({"", {0, 1, 2}, {-1e308, 1e308, 1e-310}, kRed});
  write_line_chart(dir + "/extreme.png", extreme, 300, 200);
  EXPECT_EQ(load_png(dir + "/blank.png").width, 300);

  ScatterMap map;
  map.colorbar_label = "no y label";
  map.x = {0, 1, kNaN};
  map.y = {0, 1, 2};
  map.value = {kNaN, kNaN, 1};
  write_scatter_maps(dir + "/map.png", {map, ScatterMap{}}, 2, 300, 200);
  EXPECT_EQ(load_png(dir + "/map.png").width, 600);
}

TEST(Plot, GridSize) {
  const std::string dir = iotest::scratch_dir("plot_grid");
  std::vector<LineChart> charts(3, line_and_corners());
  write_chart_grid(dir + "/grid.png", charts, 1, 400, 220);
  const Picture column = load_png(dir + "/grid.png");
  EXPECT_EQ(column.width, 400);
  EXPECT_EQ(column.height, 660);
  write_chart_grid(dir + "/grid2.png", charts, 2, 300, 200);
  const Picture grid = load_png(dir + "/grid2.png");
  EXPECT_EQ(grid.width, 600);
  EXPECT_EQ(grid.height, 400);
}

TEST(Plot, FailuresNameThePath) {
  const std::string dir = iotest::scratch_dir("plot_fail");
  const std::string bad = dir + "/missing_folder/chart.png";
  try {
    write_line_chart(bad, line_and_corners(), 300, 200);
    FAIL() << "no error";
  } catch (const RuntimeError& e) {
    EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(bad));
  const std::string ok = dir + "/small.png";
  auto expect_input_error = [&](auto call) {
    try {
      call();
      FAIL() << "no error";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(ok), std::string::npos) << e.what();
    }
  };
  expect_input_error([&] { write_line_chart(ok, line_and_corners(), 10, 10); });
  expect_input_error([&] { write_line_chart(ok, line_and_corners(), 100000, 300); });
  expect_input_error([&] { write_chart_grid(ok, {}, 1, 300, 200); });
  expect_input_error([&] { write_chart_grid(ok, {line_and_corners()}, 0, 300, 200); });
  expect_input_error([&] { write_scatter_maps(ok, {ScatterMap{}}, 1, 300, 50); });
  EXPECT_FALSE(std::filesystem::exists(ok));
}

TEST(Plot, ScatterColoursFollowTheScale) {
  const std::string path = iotest::scratch_dir("plot_map") + "/map.png";
  ScatterMap map;
  map.title = "error";
  map.x = {0, 1, 2};
  map.y = {0, 0.5, 1};
  map.value = {1e-3, 5.5e-3, 1e-2};
  map.labels = {"m1", "m2", "m3"};
  map.rects = {{-0.5, -0.5, 2.5, 1.5}};
  write_scatter_maps(path, {map}, 1, 500, 400);
  const Picture p = load_png(path);
  ASSERT_EQ(p.width, 500);
  const Spot low = find(p, colormap(0)), high = find(p, colormap(1)), mid = find(p, colormap(0.5));
  // The colour bar holds each colour too (a row or two); the markers add discs.
  ASSERT_GT(low.count, 40);
  ASSERT_GT(high.count, 40);
  ASSERT_GT(mid.count, 40);
  // Marker centres: lowest value bottom left, highest top right (colour bar excluded by x).
  const int bar_x = find(p, colormap(0.3)).x0;
  auto marker = [&](Rgb c) {
    Spot s;
    for (int y = 0; y < p.height; ++y) {
      for (int x = 0; x < bar_x - 4; ++x) {
        if (!is(p.at(x, y), c)) continue;
        ++s.count;
        s.mx += x;
        s.my += y;
      }
    }
    s.mx /= std::max(1, s.count);
    s.my /= std::max(1, s.count);
    return s;
  };
  const Spot a = marker(colormap(0)), b = marker(colormap(0.5)), c = marker(colormap(1));
  EXPECT_GT(a.count, 20);
  EXPECT_GT(b.count, 20);
  EXPECT_GT(c.count, 20);
  EXPECT_LT(a.mx, b.mx);
  EXPECT_LT(b.mx, c.mx);
  EXPECT_GT(a.my, b.my);
  EXPECT_GT(b.my, c.my);
  EXPECT_NEAR(b.mx, 0.5 * (a.mx + c.mx), 1.5);  // equal aspect keeps the middle in the middle
}

TEST(Plot, SharedScale) {
  std::vector<ScatterMap> maps(2);
  maps[0].value = {1, 2};
  maps[1].value = {kNaN, 5};
  share_color_scale(maps);
  EXPECT_EQ(maps[0].vmin, 1);
  EXPECT_EQ(maps[1].vmax, 5);
}

TEST(Plot, TicksAndLabels) {
  const std::vector<double> t = nice_ticks(0, 1, 8);
  ASSERT_GE(t.size(), 4u);
  ASSERT_LE(t.size(), 8u);
  EXPECT_EQ(t.front(), 0);
  EXPECT_EQ(t.back(), 1);
  EXPECT_EQ(nice_ticks(-0.013, 0.047, 8).size(), 6u);  // -0.01 .. 0.04 by 0.01
  EXPECT_TRUE(nice_ticks(1, 1).empty());
  EXPECT_TRUE(nice_ticks(0, 1e-320).empty());
  EXPECT_TRUE(nice_ticks(-1e308, 1e308).empty());
  EXPECT_TRUE(nice_ticks(0, std::numeric_limits<double>::infinity()).empty());
  EXPECT_EQ(format_tick(0.5, 0.5), "0.5");
  EXPECT_EQ(format_tick(1.0, 0.5), "1.0");
  EXPECT_EQ(format_tick(0.0, 0.5), "0");
  EXPECT_EQ(format_tick(0.3, 0.1), "0.3");
  EXPECT_EQ(format_tick(20, 10), "20");
  EXPECT_EQ(format_tick(1e-3, 1e-3), "0.001");
  EXPECT_EQ(format_tick(0.015, 0.005), "0.015");
  EXPECT_EQ(format_tick(1e-3, 5e-4), "1e-3");
  EXPECT_EQ(format_tick(2.5e-4, 5e-5), "2.5e-4");
  EXPECT_EQ(format_tick(3e5, 1e5), "3e5");
  EXPECT_EQ(format_tick(-1.5e-4, 5e-5), "-1.5e-4");
}

//! Sample charts for a human to look at: GEN4D_PLOT_DEMO=<folder>.
TEST(Plot, Demo) {
  const char* out = std::getenv("GEN4D_PLOT_DEMO");
  if (out == nullptr) GTEST_SKIP() << "set GEN4D_PLOT_DEMO=<folder> to write sample charts";
  const std::string dir = out;
  std::filesystem::create_directories(dir);
  LineChart res;
  res.title = "Marker residual vs time";
  res.xlabel = "time [s]";
  res.ylabel = "RMS residual [m]";
  res.log_y = true;
  Series before{"before calibration", {}, {}, palette_color(1), false, 2.0, false};
  Series after{"after calibration", {}, {}, palette_color(0), false, 2.0, false};
  Series target{"noise floor", {0, 0.02}, {2e-5, 2e-5}, palette_color(6), false, 1.5, true};
  for (int i = 0; i <= 200; ++i) {
    const double t = 1e-4 * i;
    before.x.push_back(t);
    before.y.push_back(1e-3 * (1 + 0.8 * std::sin(700 * t)) + 1e-4);
    after.x.push_back(t);
    after.y.push_back(i == 120 ? kNaN : 6e-5 * (1 + 0.5 * std::sin(900 * t + 1)) + 1e-5);
  }
  res.series = {before, after, target};
  res.shaded_x = {{0.004, 0.008}, {0.014, 0.016}};
  write_line_chart(dir + "/residual.png", res);

  std::vector<LineChart> xyz;
  for (int c = 0; c < 3; ++c) {
    LineChart ch;
    ch.title = std::string("marker 17, ") + "xyz"[c] + " displacement";
    ch.xlabel = "time [s]";
    ch.ylabel = "u [mm]";
    Series obs{"observed", {}, {}, palette_color(6), true, 1.2, false};
    Series sim0{"simulated (before)", {}, {}, palette_color(1), false, 1.5, true};
    Series sim1{"simulated (after)", {}, {}, palette_color(0), false, 2.0, false};
    for (int i = 0; i <= 60; ++i) {
      const double t = 0.0005 * i;
      obs.x.push_back(t);
      obs.y.push_back(2.0 * std::sin(200 * t + c) * std::exp(-40 * t) + 0.05 * std::sin(37.0 * i));
      sim0.x.push_back(t);
      sim0.y.push_back(1.4 * std::sin(170 * t + c) * std::exp(-25 * t));
      sim1.x.push_back(t);
      sim1.y.push_back(2.0 * std::sin(198 * t + c) * std::exp(-41 * t));
    }
    ch.series = {obs, sim0, sim1};
    xyz.push_back(ch);
  }
  write_chart_grid(dir + "/trajectories.png", xyz, 1, 900, 300);

  std::vector<ScatterMap> maps(2);
  for (int k = 0; k < 2; ++k) {
    ScatterMap& m = maps[k];
    m.title = k == 0 ? "error before" : "error after";
    m.xlabel = "X [m]";
    m.ylabel = "Z [m]";
    m.colorbar_label = "RMS error [m]";
    m.rects = {{0, 0, 0.6, 0.12}, {0.45, 0, 0.6, 0.12}};
    m.rect_colors = {Rgb{90, 90, 90}, Rgb{200, 60, 60}};
    for (int i = 0; i < 24; ++i) {
      m.x.push_back(0.025 * i + 0.01);
      m.y.push_back(0.02 + 0.08 * ((i * 7) % 5) / 4.0);
      m.value.push_back((k == 0 ? 4e-3 : 8e-4) * (0.2 + std::pow(0.04 * i, 2)));
      m.labels.push_back("M" + std::to_string(i));
    }
    m.value[5] = kNaN;
  }
  share_color_scale(maps);
  write_scatter_maps(dir + "/error_map.png", maps, 1, 900, 420);

  // Every glyph, at text scales 2 (labels) and 3 (title).
  std::string ascii;
  for (int c = 32; c < 127; ++c) ascii += char(c);
  LineChart font;
  font.title = ascii.substr(0, 48);
  font.ylabel = ascii.substr(48);
  font.xlabel = "The quick brown fox jumps over the lazy dog; gjpqy_,";
  font.series.push_back({ascii.substr(0, 48), {0, 1}, {0, 1}, palette_color(0)});
  write_line_chart(dir + "/font.png", font, 1600, 900);
}

}  // namespace
}  // namespace gen4d::io
