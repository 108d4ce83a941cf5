// Neighbour grid against brute force: random points, a lattice, points on cell
// faces, empty cells, everything in one cell, and points outside the grid.
#include <algorithm>
#include <random>
#include <set>
#include <vector>

#include "../cuda/sph/grid.h"
#include "catch.h"
#include "helpers.h"

using namespace sphray;

namespace {

// Every pair within `radius`, found through the grid, must equal brute force.
void check_against_brute_force(Backend b, const GridGeom& g, const std::vector<Vec3f>& pts, float radius) {
  const GridBuild gb = build_grid(b, g, pts);
  REQUIRE(gb.offsets.size() == size_t(g.num_cells()) + 1);
  const uint32_t inside = gb.offsets.back();
  // Sorted points and keys agree, and every cell's range holds its own key.
  std::vector<Vec3f> sorted(pts.size());
  for (size_t k = 0; k < pts.size(); ++k) sorted[k] = pts[gb.order[k]];
  for (uint32_t c = 0; c < g.num_cells(); ++c)
    for (uint32_t k = gb.offsets[c]; k < gb.offsets[c + 1]; ++k) REQUIRE(gb.keys[k] == c);
  size_t expected_inside = 0;
  for (const auto& p : pts) expected_inside += g.key_of(p) < g.num_cells();
  REQUIRE(inside == expected_inside);

  const float r2 = radius * radius;
  for (uint32_t i = 0; i < inside; ++i) {
    std::set<uint32_t> via_grid, brute;
    for_each_candidate(g, gb.offsets.data(), sorted[i], [&](uint32_t j) {
      if (length2(sorted[i] - sorted[j]) < r2) via_grid.insert(gb.order[j]);
    });
    for (uint32_t j = 0; j < inside; ++j)
      if (length2(sorted[i] - sorted[j]) < r2) brute.insert(gb.order[j]);
    REQUIRE(via_grid == brute);
  }
}

GridGeom unit_grid(int n, float cell) { return {{0, 0, 0}, cell, n, n, n}; }

}  // namespace

TEST_CASE("grid neighbours match brute force on random points", "[grid][cpu]") {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<Vec3f> pts(1500);
  for (auto& p : pts) p = {u(rng), u(rng), u(rng)};
  check_against_brute_force(Backend::Cpu, unit_grid(10, 0.1f), pts, 0.1f);
}

TEST_CASE("grid neighbours match brute force on a jittered lattice", "[grid][cpu]") {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> j(-0.002f, 0.002f);
  std::vector<Vec3f> pts;
  for (int z = 0; z < 12; ++z)
    for (int y = 0; y < 12; ++y)
      for (int x = 0; x < 12; ++x) pts.push_back({0.01f + 0.02f * x + j(rng), 0.01f + 0.02f * y + j(rng), 0.01f + 0.02f * z + j(rng)});
  check_against_brute_force(Backend::Cpu, unit_grid(5, 0.052f), pts, 0.052f);
}

TEST_CASE("grid handles points exactly on cell faces and empty cells", "[grid][cpu]") {
  std::vector<Vec3f> pts;
  for (int z = 0; z <= 4; z += 2)
    for (int y = 0; y <= 4; ++y)
      for (int x = 0; x <= 4; ++x) pts.push_back({0.25f * x, 0.25f * y, 0.25f * z});  // on faces, many cells empty
  check_against_brute_force(Backend::Cpu, unit_grid(8, 0.25f), pts, 0.25f);
}

TEST_CASE("grid handles every point in one cell", "[grid][cpu]") {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.51f, 0.59f);
  std::vector<Vec3f> pts(300);
  for (auto& p : pts) p = {u(rng), u(rng), u(rng)};
  const GridGeom g = unit_grid(10, 0.1f);
  const GridBuild gb = build_grid(Backend::Cpu, g, pts);
  const uint32_t c = g.key_of(pts[0]);
  CHECK(gb.offsets[c + 1] - gb.offsets[c] == 300);
  check_against_brute_force(Backend::Cpu, g, pts, 0.1f);
}

TEST_CASE("grid drops points outside it and keeps the rest", "[grid][cpu]") {
  std::vector<Vec3f> pts = {{0.5f, 0.5f, 0.5f}, {-0.1f, 0.5f, 0.5f}, {0.5f, 1.5f, 0.5f}, {0.55f, 0.5f, 0.5f}};
  const GridBuild gb = build_grid(Backend::Cpu, unit_grid(10, 0.1f), pts);
  CHECK(gb.offsets.back() == 2);
  check_against_brute_force(Backend::Cpu, unit_grid(10, 0.1f), pts, 0.1f);
}

TEST_CASE("grid of zero points is empty", "[grid][cpu]") {
  const GridBuild gb = build_grid(Backend::Cpu, unit_grid(4, 0.1f), {});
  for (uint32_t o : gb.offsets) CHECK(o == 0);
}
