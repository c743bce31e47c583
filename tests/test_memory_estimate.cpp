// The memory estimate of a deck (core/MemoryEstimate.hpp): voxel, node, particle and cell
// counts of analytic parts, no estimate for parts read from files, and the up-front refusal
// of a deck the machine cannot hold.
#include <gtest/gtest.h>
#include <mpi.h>

#include "core/Deck.hpp"
#include "core/Error.hpp"
#include "core/MemoryEstimate.hpp"

namespace gen4d::memory {
namespace {

Config deck(const std::string& solver, const std::string& geometry, double voxel) {
  const std::string text = "[simulation]\ndt = 0.01\nend_time = 0.1\n[solver]\nmethod = \"" +
                           solver + "\"\n[domain]\nvoxel_size = " + std::to_string(voxel) +
                           "\npadding = 1\n[[geometry]]\n" + geometry +
                           "\n[material]\nyoungs_modulus = 1e5\npoisson_ratio = 0.3\ndensity = "
                           "1000\n" +
                           (solver == "mpm" ? "model = \"fixed_corotated\"\n" : "");
  return parse_deck(text, "test.toml", ".");
}

const char* kBox = "type = \"box\"\nlo = [0, 0, 0]\nhi = [0.8, 0.2, 0.1]";

TEST(MemoryEstimate, CountsVoxelsAndNodesOfABox) {
  const Estimate e = estimate(deck("elastogen", kBox, 0.05));
  ASSERT_TRUE(e.known);
  EXPECT_EQ(e.items, 16.0 * 4 * 2);                   // solid voxels
  EXPECT_EQ(e.grid, (16.0 + 3) * (4 + 3) * (2 + 3));  // nodes with one padding cell each side
  EXPECT_DOUBLE_EQ(e.bytes, e.items * kElastoGenBytesPerVoxel + e.grid * kElastoGenBytesPerNode);
  EXPECT_NE(e.breakdown.find("128 solid voxels"), std::string::npos) << e.breakdown;
}

TEST(MemoryEstimate, CountsParticlesAndCellsOfMpm) {
  const Estimate e = estimate(deck("mpm", kBox, 0.05));
  ASSERT_TRUE(e.known);
  EXPECT_EQ(e.items, 16.0 * 4 * 2 * 8);  // 2 particles per axis and cell
  // boundary_layers 3 + 2 = 5 cells of padding each side
  EXPECT_EQ(e.grid, (16.0 + 10) * (4 + 10) * (2 + 10));
}

TEST(MemoryEstimate, SphereCountsItsVolume) {
  const Estimate e =
      estimate(deck("elastogen", "type = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1", 0.1));
  ASSERT_TRUE(e.known);
  EXPECT_NEAR(e.items, 4.0 / 3.0 * 3.14159265 * 1000, 1.0);
}

TEST(MemoryEstimate, UnknownForFileParts) {
  Config c = deck("elastogen", kBox, 0.05);
  c.geometry.front().type = "mesh";
  EXPECT_FALSE(estimate(c).known);
  EXPECT_NO_THROW(check(MPI_COMM_WORLD, c));
}

TEST(MemoryEstimate, RefusesADeckLargerThanTheMachine) {
  EXPECT_GT(available_bytes(), 0);
  EXPECT_NO_THROW(check(MPI_COMM_WORLD, deck("elastogen", kBox, 0.05)));
  // 1.6e10 voxels: far beyond any machine this runs on.
  try {
    check(MPI_COMM_WORLD, deck("elastogen", kBox, 0.0001));
    FAIL() << "no error";
  } catch (const RuntimeError& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind("test.toml: the run needs about ", 0), 0u) << msg;
    EXPECT_NE(msg.find("1.6e+10 solid voxels"), std::string::npos) << msg;
    EXPECT_NE(msg.find("available (MemAvailable)"), std::string::npos) << msg;
    EXPECT_NE(msg.find("--skip-memory-check"), std::string::npos) << msg;
  }
}

TEST(MemoryEstimate, FormatsBytes) {
  EXPECT_EQ(format_bytes(37.25 * 1024 * 1024 * 1024), "37.2 GiB");
  EXPECT_EQ(format_bytes(150.0 * 1024 * 1024), "150 MiB");
}

}  // namespace
}  // namespace gen4d::memory
