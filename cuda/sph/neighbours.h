// The neighbour loop every stage shares: particles of one grid-sorted set
// within the support radius of a position.
#pragma once

#include <cstdint>

#include "grid.h"
#include "params.h"

namespace sphray {

// Calls f(j, p_j, r, r2) for every particle j of `pts` (sorted by `g`, slab
// table `offsets`) with |r|^2 = r2 < support2, where r = x - x_j, except j == skip
// (pass the particle's own index, or UINT32_MAX for another set).
template <class F>
SPHRAY_HD SPHRAY_FORCEINLINE void for_each_neighbour(const GridGeom& g, const uint32_t* offsets, const Float4* pts,
                                                     Vec3f x, float support2, uint32_t skip, F&& f) {
  for_each_candidate(g, offsets, x, [&](uint32_t j) {
    const Float4 pj = load(pts + j);
    const Vec3f r = x - xyz(pj);
    const float r2 = length2(r);
    if (r2 >= support2 || j == skip) return;
    f(j, pj, r, r2);
  });
}

constexpr uint32_t kNoSkip = 0xffffffffu;

}  // namespace sphray
