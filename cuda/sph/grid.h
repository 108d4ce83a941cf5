// Uniform neighbour grid with cell size = SPH support radius (Green 2010,
// "Particle Simulation using CUDA"; Mishima et al. in shared/papers): a cell key
// per particle, a radix sort by key, and an offsets table (a vectorised
// lower_bound of every cell id in the sorted keys) so that cell c holds sorted
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

#include "../common/hd.h"
#include "../common/vec.h"

namespace sphray {

struct GridGeom {
  Vec3f origin;    // world position of the grid's min corner [m]
  float cell_size; // = support radius [m]
  int nx, ny, nz;

  SPHRAY_HD SPHRAY_FORCEINLINE uint32_t num_cells() const { return uint32_t(nx) * uint32_t(ny) * uint32_t(nz); }

  SPHRAY_HD SPHRAY_FORCEINLINE int coord(float p, float o) const { return int(std::floor((p - o) / cell_size)); }

  static constexpr int kSubX = 4;  // x slabs per cell in the sort key
  SPHRAY_HD SPHRAY_FORCEINLINE uint32_t num_fine_cells() const { return num_cells() * uint32_t(kSubX); }

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
};

// Calls f(j) for every particle j of a set sorted by this grid (fluid or
// boundary; `fine_offsets` is its slab table, num_fine_cells() + 1 entries) that
// may lie within one cell size (the support radius) of p: a superset of the
// neighbours, culled row by row to the support sphere (see the top of this
// file). The caller tests the distance. The culling radius is padded by 1e-3 of
// a cell so that float rounding of p and of the cell bounds never drops a
// neighbour whose distance the caller computes as just inside the support.
template <class F>
SPHRAY_HD SPHRAY_FORCEINLINE void for_each_candidate(const GridGeom& g, const uint32_t* fine_offsets, Vec3f p, F&& f) {
  const float s = g.cell_size;
  const float reach2 = (1.001f * s) * (1.001f * s);
  const int cy = g.coord(p.y, g.origin.y), cz = g.coord(p.z, g.origin.z);
  // Distance from p to the lower / upper face of its own cell in y and z.
  const float y_lo = p.y - (g.origin.y + float(cy) * s), y_hi = g.origin.y + float(cy + 1) * s - p.y;
  const float z_lo = p.z - (g.origin.z + float(cz) * s), z_hi = g.origin.z + float(cz + 1) * s - p.z;
  const int fx_last = g.nx * GridGeom::kSubX - 1;
  const float slabs_per_m = float(GridGeom::kSubX) / s;
  const uint32_t row_len = uint32_t(g.nx) * uint32_t(GridGeom::kSubX);
  for (int dz = -1; dz <= 1; ++dz) {
    const int z = cz + dz;
    if (z < 0 || z >= g.nz) continue;
    const float ez = dz < 0 ? z_lo : dz > 0 ? z_hi : 0.0f;
    const float ez2 = ez > 0.0f ? ez * ez : 0.0f;
    for (int dy = -1; dy <= 1; ++dy) {
      const int y = cy + dy;
      if (y < 0 || y >= g.ny) continue;
      const float ey = dy < 0 ? y_lo : dy > 0 ? y_hi : 0.0f;
      const float left = reach2 - ez2 - (ey > 0.0f ? ey * ey : 0.0f);
      if (left <= 0.0f) continue;  // the whole row is beyond the support
      const float rx = std::sqrt(left);
      int x0 = int(std::floor((p.x - rx - g.origin.x) * slabs_per_m));
      int x1 = int(std::floor((p.x + rx - g.origin.x) * slabs_per_m));
      x0 = x0 < 0 ? 0 : x0;
      x1 = x1 > fx_last ? fx_last : x1;
      if (x0 > x1) continue;
      const uint32_t row = (uint32_t(z) * uint32_t(g.ny) + uint32_t(y)) * row_len;
      const uint32_t begin = fine_offsets[row + uint32_t(x0)];
      const uint32_t end = fine_offsets[row + uint32_t(x1) + 1u];
      for (uint32_t j = begin; j < end; ++j) f(j);
    }
  }
}

}  // namespace sphray
