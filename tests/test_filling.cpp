// Internal filling of splat objects (PhysGaussian seed §3.7): enclosed volume of closed shells,
// the crossing-parity rule, bounded time on degenerate Gaussians, attributes of the nearest
// Gaussian, determinism, and the trained donut.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>

#include "core/Error.hpp"
#include "gaussians/DeckSplats.hpp"
#include "gaussians/Filling.hpp"
#include "gaussians/Ply.hpp"
#include "gaussians/Splats.hpp"

namespace fs = std::filesystem;
using namespace gen4d::gaussians;
using gen4d::InputError;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kC0 = 0.28209479177387814;

//! Appends n isotropic Gaussians (standard deviation sigma) on the sphere of radius R about the
//! origin (a Fibonacci lattice), SH degree 0; colour(x, y, z) gives the rgb of each, opacity
//! cycles through 0.5..0.95 so that copies can be traced.
template <class Colour>
void add_shell(SplatSet& s, double R, int n, double sigma, Colour colour) {
  const double golden = kPi * (3 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1 - (2 * i + 1.0) / n;
    const double rho = std::sqrt(1 - z * z);
    const double phi = golden * i;
    const double p[3] = {R * rho * std::cos(phi), R * rho * std::sin(phi), R * z};
    for (double v : p) s.position.push_back(v);
    for (int a = 0; a < 3; ++a) s.scale.push_back(sigma);
    s.rotation.insert(s.rotation.end(), {1.0, 0.0, 0.0, 0.0});
    s.opacity.push_back(0.5 + 0.05 * (i % 10));
    const std::array<double, 3> rgb = colour(p[0], p[1], p[2]);
    for (double c : rgb) s.sh.push_back((c - 0.5) / kC0);
  }
}

std::array<double, 3> grey(double, double, double) {
  return {0.5, 0.5, 0.5};
}

std::array<double, 3> cell_centre(const FillingResult& r, int i, int j, int k) {
  return {r.origin[0] + (i + 0.5) * r.dx, r.origin[1] + (j + 0.5) * r.dx,
          r.origin[2] + (k + 0.5) * r.dx};
}

double norm(const std::array<double, 3>& x) {
  return std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
}

//! Cells whose centre lies within radius `R` of the origin, by state.
struct Census {
  std::size_t interior_in = 0, interior_out = 0, blocked_in = 0, empty_in = 0;
};

Census census(const FillingResult& r, double R) {
  Census c;
  for (int k = 0; k < r.dims[2]; ++k)
    for (int j = 0; j < r.dims[1]; ++j)
      for (int i = 0; i < r.dims[0]; ++i) {
        const bool in = norm(cell_centre(r, i, j, k)) < R;
        switch (r.cells[r.cell_index(i, j, k)]) {
          case FillCell::interior:
            (in ? c.interior_in : c.interior_out)++;
            break;
          case FillCell::occupied:
          case FillCell::surface:
            c.blocked_in += in;
            break;
          case FillCell::empty:
            c.empty_in += in;
            break;
        }
      }
  return c;
}

std::size_t brute_nearest(const SplatSet& s, const double* q) {
  std::size_t best = 0;
  double bd = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < s.size(); ++i) {
    double d2 = 0;
    for (int a = 0; a < 3; ++a)
      d2 += (s.position[3 * i + a] - q[a]) * (s.position[3 * i + a] - q[a]);
    if (d2 < bd) {
      bd = d2;
      best = i;
    }
  }
  return best;
}

void print(const char* name, const FillingResult& r) {
  std::printf(
      "%s: grid %dx%dx%d dx %.4g, %zu surface cells (%zu particles), %zu interior cells, "
      "%zu degenerate, %zu clamped; density %.3f s, cells %.3f s, attributes %.3f s, total "
      "%.3f s\n",
      name, r.dims[0], r.dims[1], r.dims[2], r.dx, r.surface_cells, r.surface_particles,
      r.interior_cells, r.degenerate_splats, r.clamped_splats, r.seconds_density, r.seconds_cells,
      r.seconds_attributes, r.seconds_total);
}

}  // namespace

// A closed sphere of radius R made of 40k surface Gaussians. The shell's Gaussians sit on r = R,
// so its blocked cells (a Gaussian centred in them, or dense) straddle the sphere: the enclosed
// volume is the interior cells plus the blocked cells whose centre lies inside R (the shell split
// at R). That total must match 4/3 pi R^3 within 5 %; no interior cell may lie outside R, and
// the interior alone must cover the ball inside the shell's inner side (within 3 cells of R).
TEST(Filling, ClosedSphereEnclosesItsVolume) {
  const double R = 1.0;
  SplatSet s;
  add_shell(s, R, 40000, 0.025, grey);
  FillingOptions o;
  o.n_grid = 64;
  const FillingResult r = fill_interior(s, o);
  print("sphere", r);
  const Census c = census(r, R);
  const double cell = r.dx * r.dx * r.dx;
  const double ball = 4.0 / 3.0 * kPi * R * R * R;
  const double filled = (c.interior_in + c.blocked_in) * cell;
  std::printf("sphere: filled %.4f vs 4/3 pi R^3 = %.4f (%.2f %%), interior alone %.4f\n", filled,
              ball, 100 * (filled / ball - 1), r.interior_cells * cell);
  EXPECT_NEAR(filled / ball, 1.0, 0.05);
  EXPECT_EQ(c.interior_out, 0u);
  EXPECT_EQ(r.interior_cells, c.interior_in);
  const double inner = R - 3 * r.dx;
  EXPECT_GT(r.interior_cells * cell, 4.0 / 3.0 * kPi * inner * inner * inner);
  EXPECT_GT(r.surface_cells, 0u);
  EXPECT_EQ(r.degenerate_splats, 0u);
  EXPECT_EQ(r.clamped_splats, 0u);
  // One particle per interior cell, each inside its cell, with the volume's radius.
  EXPECT_EQ(r.interior_particles, r.interior_cells);
  EXPECT_EQ(r.particles.size(), r.surface_particles + r.interior_particles);
  const double radius = std::cbrt(3 * cell / (4 * kPi));
  EXPECT_DOUBLE_EQ(r.particle_radius, radius);
  for (std::size_t q = 0; q < r.particles.size(); ++q) {
    int idx[3];
    for (int a = 0; a < 3; ++a) {
      idx[a] = static_cast<int>(std::floor((r.particles.position[3 * q + a] - r.origin[a]) / r.dx));
      ASSERT_EQ(r.particles.scale[3 * q + a], radius);
    }
    const FillCell state = r.cells[r.cell_index(idx[0], idx[1], idx[2])];
    ASSERT_EQ(state, q < r.surface_particles ? FillCell::surface : FillCell::interior) << q;
  }
}

// Two concentric closed shells: a cell inside the inner one crosses two surfaces along the
// ray-cast direction +z (even: not filled); a cell between them crosses one (beside or above the
// inner shell) or three (below it): odd, filled. Cells within 3 cells of a shell, or whose +z ray
// grazes the inner shell (one run above the threshold where the ray passes tangentially, so the
// parity flips: PhysGaussian's rule), are left out of the check.
TEST(Filling, CrossingParityLeavesNestedShellHollow) {
  const double R1 = 1.0, R2 = 0.55;
  SplatSet s;
  add_shell(s, R1, 40000, 0.025, grey);
  add_shell(s, R2, 12000, 0.025, grey);
  FillingOptions o;
  o.n_grid = 64;
  const FillingResult r = fill_interior(s, o);
  print("nested", r);
  const double margin = 3 * r.dx;
  std::size_t core = 0, core_filled = 0, layer = 0, layer_filled = 0, below = 0;
  for (int k = 0; k < r.dims[2]; ++k)
    for (int j = 0; j < r.dims[1]; ++j)
      for (int i = 0; i < r.dims[0]; ++i) {
        const auto x = cell_centre(r, i, j, k);
        const double radius = norm(x), axis = std::hypot(x[0], x[1]);
        const bool filled = r.cells[r.cell_index(i, j, k)] == FillCell::interior;
        if (radius < R2 - margin) {
          ++core;
          core_filled += filled;
        } else if (radius > R2 + margin && radius < R1 - margin && std::abs(axis - R2) > margin) {
          ++layer;
          layer_filled += filled;
          below += axis < R2 && x[2] < 0;
        }
      }
  std::printf(
      "nested: core %zu cells, %zu filled; layer %zu cells (%zu below the inner shell), "
      "%zu filled\n",
      core, core_filled, layer, below, layer_filled);
  EXPECT_GT(core, 10000u);
  EXPECT_EQ(core_filled, 0u);
  EXPECT_GT(below, 1000u);
  EXPECT_EQ(layer_filled, layer);
  // Without the parity test (ray_cast_direction -1) the inner ball is filled too.
  o.ray_cast_direction = -1;
  const FillingResult all = fill_interior(s, o);
  EXPECT_GT(census(all, R2 - margin).interior_in, core / 2);
}

// A Gaussian of scale 1e6, a needle 1e6 x 1e-9 x 1e-9 and one of scale 0 among a shell: the
// support of the wide ones is cut to max_support_cells (uncut it would span ~1e8 cells a side),
// the singular ones are counted, and filling ends in bounded time.
TEST(Filling, DegenerateGaussiansAreClampedAndBounded) {
  SplatSet s;
  add_shell(s, 1.0, 20000, 0.025, grey);
  auto add = [&](std::array<double, 3> p, std::array<double, 3> scale) {
    s.position.insert(s.position.end(), p.begin(), p.end());
    s.scale.insert(s.scale.end(), scale.begin(), scale.end());
    s.rotation.insert(s.rotation.end(), {0.9, 0.1, -0.3, 0.2});
    s.opacity.push_back(0.9);
    s.sh.insert(s.sh.end(), {0.0, 0.0, 0.0});
  };
  add({0.1, 0.2, -0.1}, {1e6, 1e6, 1e6});
  add({-0.3, 0.0, 0.2}, {1e6, 1e-9, 1e-9});
  add({0.0, -0.4, 0.1}, {0.0, 0.0, 0.0});
  FillingOptions o;
  o.n_grid = 64;
  const auto t0 = std::chrono::steady_clock::now();
  const FillingResult r = fill_interior(s, o);
  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  print("degenerate", r);
  EXPECT_LT(elapsed, 5.0);
  EXPECT_EQ(r.clamped_splats, 2u);
  EXPECT_EQ(r.degenerate_splats, 2u);
  EXPECT_EQ(r.splats_in_box, s.size());
  for (double d : r.density) ASSERT_TRUE(std::isfinite(d));
  // The huge Gaussian adds ~its opacity to every cell of its cut support, no more.
  EXPECT_GT(r.interior_cells, 0u);
}

// Two halves of a sphere coloured differently (x < 0 red, x > 0 blue) with opacities that vary
// Gaussian to Gaussian: every filled particle carries exactly the opacity and SH of its nearest
// original Gaussian (checked by brute force on a sample), and so each side's particles that
// side's colour.
TEST(Filling, ParticlesTakeNearestGaussiansAttributes) {
  SplatSet s;
  add_shell(s, 1.0, 30000, 0.025, [](double x, double, double) {
    return x < 0 ? std::array<double, 3>{0.9, 0.1, 0.1} : std::array<double, 3>{0.1, 0.1, 0.9};
  });
  FillingOptions o;
  o.n_grid = 48;
  o.max_particles_per_cell = 2;
  const FillingResult r = fill_interior(s, o);
  print("halves", r);
  ASSERT_GT(r.interior_particles, 1000u);
  ASSERT_EQ(r.particles.sh.size(), 3 * r.particles.size());
  std::size_t red = 0, blue = 0;
  for (std::size_t q = 0; q < r.particles.size(); ++q) {
    const double x = r.particles.position[3 * q];
    const double* sh = &r.particles.sh[3 * q];
    const double colour_r = sh[0] * kC0 + 0.5, colour_b = sh[2] * kC0 + 0.5;
    if (x < -0.05) {
      ASSERT_NEAR(colour_r, 0.9, 1e-12) << q;
      ASSERT_NEAR(colour_b, 0.1, 1e-12) << q;
      ++red;
    } else if (x > 0.05) {
      ASSERT_NEAR(colour_r, 0.1, 1e-12) << q;
      ASSERT_NEAR(colour_b, 0.9, 1e-12) << q;
      ++blue;
    }
    if (q % 97 == 0) {
      const std::size_t near = brute_nearest(s, &r.particles.position[3 * q]);
      ASSERT_EQ(r.particles.opacity[q], s.opacity[near]) << q;
      for (int c = 0; c < 3; ++c) ASSERT_EQ(sh[c], s.sh[3 * near + c]) << q;
    }
  }
  EXPECT_GT(red, 1000u);
  EXPECT_GT(blue, 1000u);
}

// Same seed, same output bit for bit; another seed moves the particles within the same cells.
TEST(Filling, SeedDeterminesOutput) {
  SplatSet s;
  add_shell(s, 1.0, 20000, 0.025, grey);
  FillingOptions o;
  o.n_grid = 40;
  o.max_particles_per_cell = 3;
  o.seed = 7;
  const FillingResult a = fill_interior(s, o);
  const FillingResult b = fill_interior(s, o);
  ASSERT_GT(a.particles.size(), 0u);
  EXPECT_EQ(a.particles.position, b.particles.position);
  EXPECT_EQ(a.particles.opacity, b.particles.opacity);
  EXPECT_EQ(a.particles.sh, b.particles.sh);
  EXPECT_EQ(a.cells, b.cells);
  o.seed = 8;
  const FillingResult c = fill_interior(s, o);
  EXPECT_EQ(a.cells, c.cells);
  ASSERT_EQ(a.particles.size(), c.particles.size());
  EXPECT_NE(a.particles.position, c.particles.position);
  // The particles of one cell are distinct points.
  EXPECT_NE(a.particles.position[0], a.particles.position[3]);
}

TEST(Filling, RejectsBadInput) {
  SplatSet s;
  add_shell(s, 1.0, 1000, 0.025, grey);
  FillingOptions o;
  o.n_grid = 1;
  EXPECT_THROW(fill_interior(s, o), InputError);
  o = {};
  o.ray_cast_direction = 6;
  EXPECT_THROW(fill_interior(s, o), InputError);
  o = {};
  o.has_box = true;
  o.box_lo = {0, 0, 0};
  o.box_hi = {1, 0, 1};
  EXPECT_THROW(fill_interior(s, o), InputError);
  o = {};
  o.n_grid = 32;
  o.density_threshold = 0;  // every cell the shell reaches is dense: ~thousands of particles
  o.max_particles = 10;
  EXPECT_THROW(fill_interior(s, o), InputError);
  SplatSet bad = s;
  bad.position[4] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(fill_interior(bad, FillingOptions{}), InputError);
  EXPECT_THROW(fill_interior(SplatSet{}, FillingOptions{}), InputError);
}

// The trained donut with PhysGaussian's defaults: filling ends; counts and time are reported.
TEST(Filling, DeckKeyFillsTheSplatPart) {
  // A closed shell loaded as a deck's splats part: fill_cells adds the interior after the
  // Gaussians (which stay first and unchanged), all inside the shell; 0 adds nothing.
  SplatSet shell;
  add_shell(shell, 1.0, 40000, 0.025, grey);  // as ClosedSphereEnclosesItsVolume
  const std::string ply =
      (std::filesystem::path(GEN4D_BINARY_DIR) / "tests" / "filling_deck_shell.ply").string();
  write_splats_ply(ply, shell);
  gen4d::GeometryConfig g;
  g.type = "splats";
  g.file = ply;
  g.opacity_threshold = 0;
  const SplatSet plain = load_geometry_splats(g);
  g.fill_cells = 64;
  const SplatSet filled = load_geometry_splats(g);
  ASSERT_EQ(plain.size(), shell.size());
  ASSERT_GT(filled.size(), plain.size() + 1000);
  for (std::size_t i = 0; i < 3 * plain.size(); ++i)
    ASSERT_EQ(filled.position[i], plain.position[i]) << i;
  for (std::size_t i = plain.size(); i < filled.size(); ++i)
    ASSERT_LT(
        norm({filled.position[3 * i], filled.position[3 * i + 1], filled.position[3 * i + 2]}),
        1.0 + 0.2)
        << "filled particle " << i << " outside the shell";
  std::filesystem::remove(ply);
}

TEST(Filling, Donut) {
  const fs::path path =
      fs::path(GEN4D_SHARED_DIR) / "data" / "splats" / "donut" / "point_cloud.ply";
  if (!fs::exists(path)) GTEST_SKIP() << "no " << path;
  const SplatSet s = read_splats_ply(path.string());
  const FillingResult r = fill_interior(s, FillingOptions{});
  print("donut", r);
  EXPECT_EQ(r.particles.size(), r.surface_particles + r.interior_particles);
  EXPECT_GT(r.surface_cells, 0u);
  EXPECT_LT(r.seconds_total, 60.0);
}
