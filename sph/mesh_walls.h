// The obstacles' wall particles as the incompressible solvers (PBF, pbf.h;
// DFSPH, dfsph.h) see them: the points of the particle lattice inside each
// mesh within one support of its surface (pipeline/setup.cpp), static wall
// particles with the volume of the fluid's own lattice (the model of Akinci
// et al., "Versatile Rigid-Fluid Coupling for Incompressible SPH", 2012,
// with that volume in place of their per-particle sum, as the lattice fills
// the skin evenly). They add to a particle's density and to the gradient of
// its constraint and push it, but take no part in the solve: PBF's with
// lambda_i alone, DFSPH's with the particle's pressure continued
// hydrostatically (dfsph.h). The tank's planes stay mirrors
// (mirror_walls.h); the paths' test against the meshes (obstacles.h) stays
// the guarantee that nothing leaks. These walls are free-slip.
#pragma once

#include <cstdint>

#include "nsearch/grid.h"
#include "core/vec.h"

namespace sphray {

// The wall particles sorted by a grid of their own (the scene's grid, whose
// cells are two supports wide, whatever grid the fluid is sorted by).
struct WallsView {
  GridGeom grid{};                    // the grid they are sorted by
  const uint32_t* offsets = nullptr;  // slab table of `grid` (nsearch/grid.h)
  const Float4* pos = nullptr;        // x, y, z, volume
  const Float4* vel = nullptr;        // velocity over the step; null where no wall moves
  const uint8_t* near = nullptr;      // per cell: wall particles within the 27 around it; null: no walls

  // Whether wall particles may lie within two supports of x (the cells of
  // `grid` are two supports wide).
  SPHRAY_HD SPHRAY_FORCEINLINE bool near_point(Vec3f x) const { return near != nullptr && cell_near(grid, near, x); }

  // f(b, p_b, r, r2) for each wall particle b within `support` of x, r =
  // x - x_b, the candidate rows of `grid` culled to the support (the cells
  // are wider, grid.h). One exactly at x (r = 0, possible only for a particle on
  // the surface over a lattice point) is left out: its gradient has no
  // direction.
  template <class F>
  SPHRAY_HD SPHRAY_FORCEINLINE void for_each_near(Vec3f x, float support, F&& f) const {
    const float s2 = support * support;
    for (int row = 0; row < kCandidateRows; ++row) {
      uint32_t begin = 0, end = 0;
      if (!candidate_row(grid, offsets, x, row, begin, end, support)) continue;
      for (uint32_t b = begin; b < end; ++b) {
        const Float4 pb = load(pos + b);
        const Vec3f r = x - xyz(pb);
        const float r2 = length2(r);
        if (r2 < s2 && r2 > 0.0f) f(b, pb, r, r2);
      }
    }
  }
};

}  // namespace sphray
