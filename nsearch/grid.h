// Uniform neighbour grid with cell size = SPH support radius (Green 2010,
// "Particle Simulation using CUDA"; Mishima et al. in docs/references.md): a cell key
// per particle, a radix sort by key, and an offsets table (the first sorted
// index of every cell id, sort.inl) so that cell c holds sorted
// particles [offsets[c], offsets[c+1]). Keys run x-fastest, so the cells of one
// row are one contiguous range: a neighbour query reads 9 ranges, not 27.
//
// Each cell is split into kSubX slabs along x, and the sort key is the slab's
// (the "fine" key: coarse key * kSubX + slab). The coarse cells stay contiguous
// ranges (coarse offsets[c] = fine offsets[c * kSubX]; the field builder and
// the raycaster read those), and within a row the particles are ordered by slab,
// so a query reads from each of the 9 rows only the slabs that the support
// sphere reaches: rows farther than the support in y/z are skipped, and the
// others are cut to x +- sqrt(support^2 - dy^2 - dz^2). That tests about 15
// cell volumes of candidates instead of 27 (the sphere is 4.2). Particles
// outside the grid get key = num_cells (coarse) / num_fine_cells (fine) and sort to the
// end, where they are dropped (the solver counts them).
#pragma once

#include <cstdint>

#include "core/hd.h"
#include "core/vec.h"

namespace sphray {

struct GridGeom {
  Vec3f origin;    // world position of the grid's min corner [m]
  float cell_size; // = support radius [m]
  int nx, ny, nz;

  SPHRAY_HD SPHRAY_FORCEINLINE uint32_t num_cells() const { return uint32_t(nx) * uint32_t(ny) * uint32_t(nz); }

  SPHRAY_HD SPHRAY_FORCEINLINE int coord(float p, float o) const { return int(std::floor((p - o) / cell_size)); }

  static constexpr int kSubX = 4;  // x slabs per cell in the sort key
  SPHRAY_HD SPHRAY_FORCEINLINE uint32_t num_fine_cells() const { return num_cells() * uint32_t(kSubX); }
  // Whether every slab key, and the one past them, fits the 32-bit keys and
  // slab tables (num_fine_cells() wraps beyond that).
  bool fine_cells_indexable() const { return double(nx) * double(ny) * double(nz) * kSubX < 0xffffffffull; }

  // Slab index along x (floor((x - origin) / (cell_size / kSubX))). The coarse
  // x cell is slab / kSubX, so coarse and fine keys never disagree.
  SPHRAY_HD SPHRAY_FORCEINLINE int fine_coord_x(float x) const {
    return int(std::floor((x - origin.x) * (float(kSubX) / cell_size)));
  }

  // Fine (slab) key of a world position, or num_fine_cells() when it is outside.
  SPHRAY_HD SPHRAY_FORCEINLINE uint32_t fine_key_of(Vec3f p) const {
    const int fx = fine_coord_x(p.x), cy = coord(p.y, origin.y), cz = coord(p.z, origin.z);
    if (fx < 0 || cy < 0 || cz < 0 || fx >= nx * kSubX || cy >= ny || cz >= nz) return num_fine_cells();
    return (uint32_t(cz) * uint32_t(ny) + uint32_t(cy)) * uint32_t(nx) * uint32_t(kSubX) + uint32_t(fx);
  }

  // Linear (coarse) cell key of a world position, or num_cells() when it is outside.
  SPHRAY_HD SPHRAY_FORCEINLINE uint32_t key_of(Vec3f p) const { return fine_key_of(p) / uint32_t(kSubX); }

  // The same origin and extent in cells half as wide: each cell split in
  // two along every axis (PBF's step grid, sph/pbf_solver.inl).
  GridGeom halved() const { return {origin, 0.5f * cell_size, 2 * nx, 2 * ny, 2 * nz}; }
};

// The candidate rows of a query at p: the (2 Span + 1)^2 rows (dz, dy in
// -Span..Span, row = (dz + Span) * (2 Span + 1) + (dy + Span)) of the cells
// around p's cell (Span 1: the 9 rows of the 3 x 3 cells), each one
// contiguous range of a set sorted by this grid (fluid or boundary;
// `fine_offsets` is its slab table, num_fine_cells() + 1 entries), culled to
// the support sphere (see the top of this file). Returns false for a row
// outside the grid or wholly beyond the support; otherwise sets [begin, end)
// (possibly empty). The culling radius is padded by 1e-3 of a cell so that
// float rounding of p and of the cell bounds never drops a neighbour whose
// distance the caller computes as just inside the support. `reach` (at most
// Span cells; 0: one cell, with Span 1) culls to that sphere, for a search
// radius below the cell size (the PBF solver's) or, with a wider Span, above
// it (the anisotropy pass's, field/anisotropy.h). Pure function of (g,
// fine_offsets, p, row, reach), so a query that walks the rows again (the
// pair masks, pair_masks.h) sees the same ranges.
template <int Span>
constexpr int candidate_rows() { return (2 * Span + 1) * (2 * Span + 1); }
constexpr int kCandidateRows = candidate_rows<1>();

template <int Span = 1>
SPHRAY_HD SPHRAY_FORCEINLINE bool candidate_row(const GridGeom& g, const uint32_t* fine_offsets, Vec3f p, int row,
                                                uint32_t& begin, uint32_t& end, float reach = 0.0f) {
  static_assert(Span >= 1, "a query reads at least the rows beside its own");
  const float s = g.cell_size;
  const float pad = reach > 0.0f ? reach + 0.001f * s : 1.001f * s;
  const float reach2 = pad * pad;
  constexpr int side = 2 * Span + 1;
  const int dz = row / side - Span, dy = row % side - Span;
  const int cz = g.coord(p.z, g.origin.z), z = cz + dz;
  const int cy = g.coord(p.y, g.origin.y), y = cy + dy;
  if (z < 0 || z >= g.nz || y < 0 || y >= g.ny) return false;
  // Distance from p to the near face of the row's cells (0 for the row
  // through p). Both forms compute it; with Span 1 the solvers' neighbour
  // kernels keep the registers they were measured with (the second form
  // changed them by up to 8), with Span 2 the anisotropy pass takes 40
  // registers instead of the first form's 46.
  float ez, ey;
  if constexpr (Span == 1) {
    ez = dz < 0 ? p.z - (g.origin.z + float(cz) * s) : dz > 0 ? g.origin.z + float(cz + 1) * s - p.z : 0.0f;
    ey = dy < 0 ? p.y - (g.origin.y + float(cy) * s) : dy > 0 ? g.origin.y + float(cy + 1) * s - p.y : 0.0f;
  } else {
    ez = dz < 0 ? p.z - (g.origin.z + float(z + 1) * s) : dz > 0 ? g.origin.z + float(z) * s - p.z : 0.0f;
    ey = dy < 0 ? p.y - (g.origin.y + float(y + 1) * s) : dy > 0 ? g.origin.y + float(y) * s - p.y : 0.0f;
  }
  const float left = reach2 - (ez > 0.0f ? ez * ez : 0.0f) - (ey > 0.0f ? ey * ey : 0.0f);
  if (left <= 0.0f) return false;  // the whole row is beyond the support
  const float rx = std::sqrt(left);
  const float slabs_per_m = float(GridGeom::kSubX) / s;
  const int fx_last = g.nx * GridGeom::kSubX - 1;
  int x0 = int(std::floor((p.x - rx - g.origin.x) * slabs_per_m));
  int x1 = int(std::floor((p.x + rx - g.origin.x) * slabs_per_m));
  x0 = x0 < 0 ? 0 : x0;
  x1 = x1 > fx_last ? fx_last : x1;
  if (x0 > x1) return false;
  const uint32_t first = (uint32_t(z) * uint32_t(g.ny) + uint32_t(y)) * uint32_t(g.nx) * uint32_t(GridGeom::kSubX);
  begin = fine_offsets[first + uint32_t(x0)];
  end = fine_offsets[first + uint32_t(x1) + 1u];
  return true;
}

// Calls f(j) for every particle j of a set sorted by this grid that may lie
// within one cell size (the support radius) of p: a superset of the
// neighbours, the candidate rows in order, j ascending within a row. The
// caller tests the distance.
template <class F>
SPHRAY_HD SPHRAY_FORCEINLINE void for_each_candidate(const GridGeom& g, const uint32_t* fine_offsets, Vec3f p, F&& f) {
  for (int row = 0; row < kCandidateRows; ++row) {
    uint32_t begin = 0, end = 0;
    if (!candidate_row(g, fine_offsets, p, row, begin, end)) continue;
    for (uint32_t j = begin; j < end; ++j) f(j);
  }
}

// near[c] = 1 where any particle of a set sorted by this grid (slab table
// `fine_offsets`) lies in the 3 x 3 x 3 cells around cell c, else 0. With
// cells one support radius wide, a point in a cell whose flag is 0 has no
// particle of the set within its support: the loops that would find nothing
// there skip their candidate rows (the dry wall particles of the wall
// pressure, the fluid far from every wall in the wall pair masks).
struct CellsNear {
  GridGeom grid;
  const uint32_t* fine_offsets;
  uint8_t* near;
  SPHRAY_HD void operator()(uint32_t c) const {
    const int nx = grid.nx, ny = grid.ny, nz = grid.nz;
    const int x = int(c % uint32_t(nx)), y = int(c / uint32_t(nx) % uint32_t(ny)), z = int(c / (uint32_t(nx) * uint32_t(ny)));
    const int x0 = x > 0 ? x - 1 : 0, x1 = x + 1 < nx ? x + 1 : nx - 1;
    uint8_t any = 0;
    for (int zz = z - 1; zz <= z + 1; ++zz) {
      for (int yy = y - 1; yy <= y + 1; ++yy) {
        if (zz < 0 || zz >= nz || yy < 0 || yy >= ny) continue;
        const uint32_t row = (uint32_t(zz) * uint32_t(ny) + uint32_t(yy)) * uint32_t(nx);
        const uint32_t k = uint32_t(GridGeom::kSubX);
        any |= uint8_t(fine_offsets[(row + uint32_t(x1) + 1u) * k] > fine_offsets[(row + uint32_t(x0)) * k]);
      }
    }
    near[c] = any;
  }
};

// Whether the set flagged in `near` (CellsNear) may have a particle within
// one cell of p: the cell's flag, or true outside the grid (no flag there; the
// caller then runs its loop as without flags).
SPHRAY_HD SPHRAY_FORCEINLINE bool cell_near(const GridGeom& g, const uint8_t* near, Vec3f p) {
  const uint32_t c = g.key_of(p);
  return c >= g.num_cells() || near[c] != 0;
}

}  // namespace sphray
