// Wall pressure of the generalized wall boundary condition of Adami, Hu &
// Adams (2012, eq. 27): each wall particle takes the kernel-weighted pressure
// of the fluid around it plus the hydrostatic difference between them,
//   p_w = (sum_f p_f W_wf + g . sum_f rho_f (x_w - x_f) W_wf) / sum_f W_wf
// (static walls, so no wall acceleration term). A wall then pushes with the
// pressure the liquid would have there, whatever one particle's own density
// does, which is what keeps a column at rest hydrostatic to the floor. Walls
// only push: p_w is clamped at 0 (Adami et al. sec. 3.2 discuss the same).
#pragma once

#include <cstdint>

#include "nsearch/pair_masks.h"
#include "params.h"
#include "particles.h"

namespace sphray {

// The density of a wall particle at a pressure (eos.h).
SPHRAY_HD SPHRAY_FORCEINLINE float tait_density(const SphParams& p, float pressure) {
  return tait_density(p.tait_b, p.rest_density, pressure);
}

// What the pair loop reads of a wall particle: p_w / rho_w^2 and rho_w,
// computed once per wall particle and step rather than per fluid neighbour.
struct alignas(8) WallState {
  float p_over_rho2;
  float rho;
};

// K: the scene's kernel (prm.kernel.type), fixed at compile time in the loop.
template <KernelType K>
struct WallPressure {
  SphParams prm;
  GridGeom grid;
  FluidIn fluid;
  const uint8_t* fluid_near;  // CellsNear of the fluid (grid.h): a dry wall particle skips its rows
  const Float4* boundary;  // sorted boundary: x, y, z, volume
  WallState* wall;         // out, per boundary particle

  SPHRAY_HD void operator()(uint32_t b) const {
    const Vec3f xb = xyz(boundary[b]);
    const float support2 = prm.kernel.support() * prm.kernel.support();
    float sum_w = 0.0f, sum_pw = 0.0f;
    Vec3f sum_rho_r = {0.0f, 0.0f, 0.0f};
    // A dry wall particle (no fluid in the 27 cells around it) skips its rows:
    // its sums are empty (p_w = 0) either way.
    if (cell_near(grid, fluid_near, xb)) for_each_neighbour(grid, fluid.offsets, fluid.pos_rho, xb, support2, kNoSkip, [&](uint32_t f, Float4 pf, Vec3f r, float r2) {
      // r^2 >= (dx / 2)^2 here: the fluid stays inside the tank's faces, the
      // wall particles lie half a spacing and more outside them.
      const float w = prm.kernel.template W_for<K>(r2 * inv_sqrt(r2));
      sum_w += w;
      sum_pw += load(fluid.flow + f).w * pf.w * pf.w * w;
      sum_rho_r += (pf.w * w) * r;
    });
    const float p = sum_w > 0.0f ? (sum_pw + dot(prm.gravity, sum_rho_r)) / sum_w : 0.0f;
    const float p_w = p > 0.0f ? p : 0.0f;
    const float rho_w = p_w > 0.0f ? tait_density(prm, p_w) : prm.rest_density;  // the same value, without the pow
    wall[b] = {p_w / (rho_w * rho_w), rho_w};
  }
};

}  // namespace sphray
