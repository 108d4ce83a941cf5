// Neighbour grid against brute force: random points, a lattice, points on cell
// faces, empty cells, everything in one cell, and points outside the grid; the
// pair masks (nsearch/pair_masks.h) against the direct loop on the same inputs.
#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <set>
#include <vector>

#include "nsearch/grid.h"
#include "nsearch/pair_masks.h"
#include "catch.h"
#include "helpers.h"
#include "nsearch_probe.h"

using namespace sphray;

namespace {

// The pair masks' walk visits exactly the direct loop's neighbours, in its
// order, for a query set against itself (skipping the query) and against
// another set, with every word stored, a few stored (a query needing more
// takes the direct loop), and none.
void check_pair_masks(const GridGeom& g, const GridBuild& gb, const std::vector<Vec3f>& sorted, uint32_t inside,
                      float radius) {
  const float r2 = radius * radius;
  std::vector<Float4> pts(inside);
  for (uint32_t i = 0; i < inside; ++i) pts[i] = {sorted[i].x, sorted[i].y, sorted[i].z, 0.0f};
  // The near-cell flags (grid.h) against brute force: cell c is flagged iff a
  // point lies in a cell at most one away in each axis.
  std::vector<uint8_t> near(g.num_cells());
  const CellsNear flag{g, gb.fine_offsets.data(), near.data()};
  for (uint32_t c = 0; c < g.num_cells(); ++c) flag(c);
  std::vector<uint8_t> brute(g.num_cells(), 0);
  for (uint32_t k = 0; k < inside; ++k) {
    const int x = int(std::floor((sorted[k].x - g.origin.x) / g.cell_size)), y = g.coord(sorted[k].y, g.origin.y),
              z = g.coord(sorted[k].z, g.origin.z);
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int cx = x + dx, cy = y + dy, cz = z + dz;
          if (cx < 0 || cy < 0 || cz < 0 || cx >= g.nx || cy >= g.ny || cz >= g.nz) continue;
          brute[(size_t(cz) * g.ny + cy) * g.nx + cx] = 1;
        }
  }
  REQUIRE(near == brute);
  for (uint32_t capacity : {64u, 3u, 0u})
    for (bool self : {true, false}) {
      std::vector<PairWord> words(size_t(capacity) * inside + 1, PairWord{0xdeadbeefu, 0u});
      std::vector<uint32_t> count(inside);
      const PairMask m{words.data(), count.data(), inside, capacity};
      const BuildPairMask build{g, gb.fine_offsets.data(), pts.data(), pts.data(), r2, self, m};
      for (uint32_t i = 0; i < inside; ++i) build(i);
      CHECK(words.back().base == 0xdeadbeefu);  // nothing written past the capacity
      for (uint32_t c : count) REQUIRE(c <= capacity + 1);
      uint32_t overflowed = 0, with_neighbours = 0;
      for (uint32_t i = 0; i < inside; ++i) {
        const uint32_t skip = self ? i : kNoSkip;
        std::vector<uint32_t> walked, direct;
        auto visit = [&](uint32_t j, Float4, Vec3f, float) { walked.push_back(j); };
        const bool complete = count[i] <= capacity;
        overflowed += !complete;
        // No stored word is empty: the mask walk takes a word's lowest bit
        // without testing the word first (for_each_masked).
        for (uint32_t w = 0; complete && w < count[i]; ++w) REQUIRE(words[size_t(w) * inside + i].bits != 0u);
        if (complete) for_each_pair<false>(g, gb.fine_offsets.data(), pts.data(), sorted[i], r2, skip, m, i, visit);
        else for_each_pair<true>(g, gb.fine_offsets.data(), pts.data(), sorted[i], r2, skip, m, i, visit);
        for_each_neighbour(g, gb.fine_offsets.data(), pts.data(), sorted[i], r2, skip,
                           [&](uint32_t j, Float4, Vec3f, float) { direct.push_back(j); });
        INFO("capacity " << capacity << ", self " << self << ", query " << i);
        REQUIRE(walked == direct);
        REQUIRE(std::count(direct.begin(), direct.end(), i) == (self ? 0 : 1));
        with_neighbours += !direct.empty();
      }
      // Capacity 0: every query with a neighbour overflows; the mask walk of an
      // overflowed query visits nothing (the direct launch serves it).
      if (capacity == 0) CHECK(overflowed == with_neighbours);
    }
}

// Every pair within `radius`, found through the grid, must equal brute force.
void check_against_brute_force(Backend b, const GridGeom& g, const std::vector<Vec3f>& pts, float radius) {
  const GridBuild gb = build_grid(b, g, pts);
  REQUIRE(gb.offsets.size() == size_t(g.num_cells()) + 1);
  REQUIRE(gb.fine_offsets.size() == size_t(g.num_fine_cells()) + 1);
  // The coarse table is the slab table at every kSubX-th slab.
  for (uint32_t c = 0; c <= g.num_cells(); ++c) REQUIRE(gb.offsets[c] == gb.fine_offsets[size_t(c) * GridGeom::kSubX]);
  const uint32_t inside = gb.offsets.back();
  // Sorted points and keys agree, and every cell's range holds its own key.
  std::vector<Vec3f> sorted(pts.size());
  for (size_t k = 0; k < pts.size(); ++k) sorted[k] = pts[gb.order[k]];
  for (uint32_t c = 0; c < g.num_cells(); ++c)
    for (uint32_t k = gb.offsets[c]; k < gb.offsets[c + 1]; ++k) REQUIRE(gb.keys[k] == c);
  // Within a cell, points are ordered by their x slab, and every slab range holds its own slab.
  for (uint32_t k = 0; k < g.num_fine_cells(); ++k)
    for (uint32_t i = gb.fine_offsets[k]; i < gb.fine_offsets[k + 1]; ++i) REQUIRE(g.fine_key_of(sorted[i]) == k);
  size_t expected_inside = 0;
  for (const auto& p : pts) expected_inside += g.key_of(p) < g.num_cells();
  REQUIRE(inside == expected_inside);

  const float r2 = radius * radius;
  for (uint32_t i = 0; i < inside; ++i) {
    std::set<uint32_t> via_grid, brute;
    for_each_candidate(g, gb.fine_offsets.data(), sorted[i], [&](uint32_t j) {
      if (length2(sorted[i] - sorted[j]) < r2) via_grid.insert(gb.order[j]);
    });
    for (uint32_t j = 0; j < inside; ++j)
      if (length2(sorted[i] - sorted[j]) < r2) brute.insert(gb.order[j]);
    REQUIRE(via_grid == brute);
  }
  check_pair_masks(g, gb, sorted, inside, radius);
  // The library's build-and-walk (what the gpu test compares across backends) agrees too.
  const PairMaskBuild pm = build_pair_masks(b, g, pts, radius, 16);
  REQUIRE(pm.neighbours.size() == inside);
  for (uint32_t i = 0; i < inside; ++i) {
    std::vector<uint32_t> direct;
    for_each_candidate(g, gb.fine_offsets.data(), sorted[i], [&](uint32_t j) {
      if (j != i && length2(sorted[i] - sorted[j]) < radius * radius) direct.push_back(j);
    });
    REQUIRE(pm.neighbours[i] == direct);
  }
}

GridGeom unit_grid(int n, float cell) { return {{0, 0, 0}, cell, n, n, n}; }

std::vector<Vec3f> random_points(size_t n, float lo, float hi, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(lo, hi);
  std::vector<Vec3f> pts(n);
  for (auto& p : pts) p = {u(rng), u(rng), u(rng)};
  return pts;
}

}  // namespace

TEST_CASE("grid neighbours match brute force on random points", "[grid][cpu]") {
  const std::vector<Vec3f> pts = random_points(1500, 0.0f, 1.0f, 7);
  check_against_brute_force(Backend::Cpu, unit_grid(10, 0.1f), pts, 0.1f);
}

TEST_CASE("a halved grid covers the same box in cells half as wide, and finds the neighbours", "[grid][cpu]") {
  // PBF's step grid (GridGeom::halved): every point's cell in it lies inside
  // its cell of the wide grid, points outside one are outside the other, and
  // a search of half the radius finds the brute-force neighbours.
  const GridGeom wide{{-0.05f, 0.02f, 0.0f}, 0.1f, 10, 7, 5};
  const GridGeom fine = wide.halved();
  CHECK(fine.cell_size == 0.05f);
  CHECK(fine.nx * fine.cell_size == Approx(wide.nx * wide.cell_size));
  CHECK(fine.nz * fine.cell_size == Approx(wide.nz * wide.cell_size));
  const std::vector<Vec3f> pts = random_points(3000, -0.1f, 1.1f, 29);
  // A cell key's x, y, z (keys run x-fastest).
  auto cell = [](const GridGeom& g, uint32_t key) {
    const uint32_t nx = uint32_t(g.nx), ny = uint32_t(g.ny);
    return std::array<uint32_t, 3>{key % nx, key / nx % ny, key / (nx * ny)};
  };
  size_t inside = 0;
  for (const Vec3f& p : pts) {
    const uint32_t c = wide.key_of(p), f = fine.key_of(p);
    REQUIRE((c == wide.num_cells()) == (f == fine.num_cells()));
    if (c == wide.num_cells()) continue;
    ++inside;
    const std::array<uint32_t, 3> cw = cell(wide, c), cf = cell(fine, f);
    for (int a = 0; a < 3; ++a) CHECK(cf[size_t(a)] / 2 == cw[size_t(a)]);
  }
  CHECK(inside > 300);                 // about a fifth of the cube lies in the grid
  CHECK(pts.size() - inside > 1000);  // and the rest outside
  check_against_brute_force(Backend::Cpu, unit_grid(10, 0.1f).halved(), random_points(1500, 0.0f, 1.0f, 31), 0.05f);
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

TEST_CASE("grid finds pairs just inside the support across diagonal rows", "[grid][cpu]") {
  // Partners at 0.9999 of the support in random directions: most pairs lie in
  // a side or corner row, where the query cuts the row to the sphere.
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.15f, 0.85f), a(-1.0f, 1.0f);
  const float s = 0.1f;
  std::vector<Vec3f> pts;
  while (pts.size() < 1200) {
    Vec3f d{a(rng), a(rng), a(rng)};
    const float l = std::sqrt(length2(d));
    if (l < 0.1f || l > 1.0f) continue;
    const Vec3f c{u(rng), u(rng), u(rng)};
    pts.push_back(c);
    pts.push_back(c + (0.9999f * s / l) * d);
  }
  check_against_brute_force(Backend::Cpu, unit_grid(10, s), pts, s);
}

TEST_CASE("grid queries read about half the candidates of the 27 cells", "[grid][cpu]") {
  // Uniform points: the culled query must test well under the 27 cells' worth
  // (expected about 15 cell volumes: grid.h), and still find every neighbour.
  const std::vector<Vec3f> pts = random_points(20000, 0.0f, 1.0f, 9);
  const GridGeom g = unit_grid(10, 0.1f);
  const GridBuild gb = build_grid(Backend::Cpu, g, pts);
  double culled = 0, full = 0;
  size_t queries = 0;
  for (uint32_t i = 0; i < gb.offsets.back(); ++i) {
    const Vec3f p = pts[gb.order[i]];
    const int cx = g.coord(p.x, 0.0f), cy = g.coord(p.y, 0.0f), cz = g.coord(p.z, 0.0f);
    if (cx < 1 || cy < 1 || cz < 1 || cx > 8 || cy > 8 || cz > 8) continue;  // interior cells only
    ++queries;
    for_each_candidate(g, gb.fine_offsets.data(), p, [&](uint32_t) { culled += 1; });
    for (int z = cz - 1; z <= cz + 1; ++z)
      for (int y = cy - 1; y <= cy + 1; ++y) {
        const uint32_t row = uint32_t((z * g.ny + y) * g.nx);
        full += gb.offsets[row + uint32_t(cx) + 2] - gb.offsets[row + uint32_t(cx) - 1];
      }
  }
  REQUIRE(queries > 5000);
  const double ratio = culled / full;
  INFO("candidates per query: " << culled / queries << " culled, " << full / queries << " in 27 cells");
  CHECK(ratio < 0.6);
  CHECK(ratio > 4.18 / 27.0);  // never fewer than the sphere holds
}

TEST_CASE("grid handles points exactly on cell faces and empty cells", "[grid][cpu]") {
  std::vector<Vec3f> pts;
  for (int z = 0; z <= 4; z += 2)
    for (int y = 0; y <= 4; ++y)
      for (int x = 0; x <= 4; ++x) pts.push_back({0.25f * x, 0.25f * y, 0.25f * z});  // on faces, many cells empty
  check_against_brute_force(Backend::Cpu, unit_grid(8, 0.25f), pts, 0.25f);
}

TEST_CASE("grid handles every point in one cell", "[grid][cpu]") {
  const std::vector<Vec3f> pts = random_points(300, 0.51f, 0.59f, 3);
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

TEST_CASE("a warp-built mask word keeps only the query's own candidates", "[grid][cpu]") {
  // The GPU build tests a warp's union of candidates and keeps, per lane, the
  // bits of BuildPairMask::own_bits: within [begin, end) and not the query itself.
  std::mt19937 rng(23);
  std::uniform_int_distribution<uint32_t> u(0, 200);
  for (int trial = 0; trial < 20000; ++trial) {
    const uint32_t base = u(rng), begin = u(rng), end = begin + u(rng) % 80;
    const uint32_t skip = trial % 3 == 0 ? kNoSkip : u(rng);
    uint32_t expected = 0;
    for (uint32_t k = 0; k < 32; ++k) {
      const uint32_t j = base + k;
      if (j >= begin && j < end && j != skip) expected |= 1u << k;
    }
    INFO("base " << base << " begin " << begin << " end " << end << " skip " << skip);
    REQUIRE(BuildPairMask::own_bits(base, begin, end, skip) == expected);
  }
}

TEST_CASE("pair masks against another set skip queries in unflagged cells and lose no neighbour", "[grid][cpu]") {
  // A "wall": points in a slab at x < 0.15; queries everywhere in the unit
  // cube. With the wall's near-cell flags (CellsNear), a query more than a
  // cell from the slab stores no words, and every query still walks exactly
  // the direct loop's wall neighbours.
  const GridGeom g = unit_grid(10, 0.1f);
  std::vector<Vec3f> wall = random_points(3000, 0.0f, 1.0f, 21);
  for (auto& p : wall) p.x *= 0.15f;
  const GridBuild gb = build_grid(Backend::Cpu, g, wall);
  const uint32_t nw = gb.offsets.back();
  REQUIRE(nw == wall.size());
  std::vector<Float4> sorted(nw);
  for (uint32_t k = 0; k < nw; ++k) {
    const Vec3f p = wall[gb.order[k]];
    sorted[k] = {p.x, p.y, p.z, 0.0f};
  }
  std::vector<uint8_t> near(g.num_cells());
  for (uint32_t c = 0; c < g.num_cells(); ++c) CellsNear{g, gb.fine_offsets.data(), near.data()}(c);
  const std::vector<Vec3f> queries = random_points(2000, 0.0f, 1.0f, 22);
  std::vector<Float4> q(queries.size());
  for (size_t k = 0; k < q.size(); ++k) q[k] = {queries[k].x, queries[k].y, queries[k].z, 0.0f};
  const uint32_t nq = uint32_t(q.size()), capacity = 64;
  std::vector<PairWord> words(size_t(capacity) * nq);
  std::vector<uint32_t> count(nq);
  const PairMask m{words.data(), count.data(), nq, capacity};
  const float r2 = 0.1f * 0.1f;
  const BuildPairMask build{g, gb.fine_offsets.data(), sorted.data(), q.data(), r2, false, m, near.data()};
  uint32_t skipped = 0, with_neighbours = 0;
  for (uint32_t i = 0; i < nq; ++i) {
    build(i);
    std::vector<uint32_t> walked, direct;
    REQUIRE(count[i] <= capacity);
    for_each_pair<false>(g, gb.fine_offsets.data(), sorted.data(), queries[i], r2, kNoSkip, m, i,
                         [&](uint32_t j, Float4, Vec3f, float) { walked.push_back(j); });
    for_each_neighbour(g, gb.fine_offsets.data(), sorted.data(), queries[i], r2, kNoSkip,
                       [&](uint32_t j, Float4, Vec3f, float) { direct.push_back(j); });
    INFO("query " << i << " at x = " << queries[i].x);
    REQUIRE(walked == direct);
    skipped += !cell_near(g, near.data(), queries[i]);
    with_neighbours += !direct.empty();
    if (queries[i].x >= 0.3f) CHECK(count[i] == 0);  // two cells from the slab: flagged off
  }
  // The slab's cells and their neighbours (x cells 0..2) are flagged, the rest not.
  CHECK(skipped > nq / 2);
  CHECK(with_neighbours > nq / 10);
  // The library's build-and-walk with queries (what the gpu test compares across backends) agrees.
  const PairMaskBuild pm = build_pair_masks(Backend::Cpu, g, wall, 0.1f, capacity, &queries);
  REQUIRE(pm.neighbours.size() == nq);
  for (uint32_t i = 0; i < nq; ++i) {
    std::vector<uint32_t> direct;
    for_each_neighbour(g, gb.fine_offsets.data(), sorted.data(), queries[i], r2, kNoSkip,
                       [&](uint32_t j, Float4, Vec3f, float) { direct.push_back(j); });
    REQUIRE(pm.neighbours[i] == direct);
  }
}

TEST_CASE("the three-way split of the passes' particles keeps each list in grid order", "[grid][cpu]") {
  for (uint32_t n : {0u, 1u, 7u, 100000u}) {
    INFO("n = " << n);
    test::check_partition_three(Backend::Cpu, n, 3 + n);
  }
}
