// Uniform neighbour grid with cell size = SPH support radius (Green 2010,
// "Particle Simulation using CUDA"; Mishima et al. in shared/papers): a cell key
// per particle, a radix sort by key, and an offsets table (a vectorised
// lower_bound of every cell id in the sorted keys) so that cell c holds sorted
// particles [offsets[c], offsets[c+1]). Keys run x-fastest, so the three
// cells x-1..x+1 of one row are one contiguous range: a neighbour query reads 9
// ranges instead of 27. Particles outside the grid get key = num_cells and sort
// to the end, where they are dropped (the solver counts them).
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

  // Linear cell key of a world position, or num_cells() when it is outside.
  SPHRAY_HD SPHRAY_FORCEINLINE uint32_t key_of(Vec3f p) const {
    const int cx = coord(p.x, origin.x), cy = coord(p.y, origin.y), cz = coord(p.z, origin.z);
    if (cx < 0 || cy < 0 || cz < 0 || cx >= nx || cy >= ny || cz >= nz) return num_cells();
    return (uint32_t(cz) * uint32_t(ny) + uint32_t(cy)) * uint32_t(nx) + uint32_t(cx);
  }
};

// Calls f(j) for every particle j stored in the 27 cells around position p
// (candidates only: the caller tests the distance). Works for any particle
// set sorted by this grid (fluid or boundary).
template <class F>
SPHRAY_HD SPHRAY_FORCEINLINE void for_each_candidate(const GridGeom& g, const uint32_t* offsets, Vec3f p, F&& f) {
  const int cx = g.coord(p.x, g.origin.x), cy = g.coord(p.y, g.origin.y), cz = g.coord(p.z, g.origin.z);
  const int x0 = cx - 1 < 0 ? 0 : cx - 1;
  const int x1 = cx + 1 >= g.nx ? g.nx - 1 : cx + 1;
  if (x0 > x1) return;
  for (int z = cz - 1; z <= cz + 1; ++z) {
    if (z < 0 || z >= g.nz) continue;
    for (int y = cy - 1; y <= cy + 1; ++y) {
      if (y < 0 || y >= g.ny) continue;
      const uint32_t row = (uint32_t(z) * uint32_t(g.ny) + uint32_t(y)) * uint32_t(g.nx);
      const uint32_t begin = offsets[row + uint32_t(x0)];
      const uint32_t end = offsets[row + uint32_t(x1) + 1u];
      for (uint32_t j = begin; j < end; ++j) f(j);
    }
  }
}

}  // namespace sphray
