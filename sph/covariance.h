// The neighbour sums of the anisotropic kernels (field/anisotropy.h; Yu &
// Turk 2013): per particle, over its neighbours j within the radius r,
// w = 1 - q^3 with q = |x_j - x_i| / r, and d = (x_j - x_i) / r,
//   W = 1 + sum w (the particle itself weighs 1), M = sum w d,
//   S = sum w d d^T (six terms), and the count of neighbours; with the
// tank's walls as mirrors (field.anisotropy.mirror_walls), the images of i
// and of its neighbours across the walls within r count as neighbours.
// The field builder turns them into an ellipsoid. They are summed either by
// the field's own pass (ComputeAnisotropy) or, where the solver's neighbour
// loop already visits every neighbour within r, inside it on the steps that
// reach an output frame (WCSPH's pair loop, interaction.h), so that the
// field's pass is skipped. Offsets in units of r keep the sums O(1) in float.
#pragma once

#include <cmath>
#include <cstdint>

#include "core/vec.h"

namespace sphray {

struct CovarianceSums {
  float w = 1.0f, mx = 0.0f, my = 0.0f, mz = 0.0f;
  float sxx = 0.0f, syy = 0.0f, szz = 0.0f, sxy = 0.0f, sxz = 0.0f, syz = 0.0f;
  float count = 0.0f;

  // Adds a neighbour at offset d = (x_j - x_i) / r with q2 = |d|^2; one
  // beyond the radius adds nothing (selected, not branched: the GPU's lanes
  // stay together).
  SPHRAY_HD SPHRAY_FORCEINLINE void add(float dx, float dy, float dz, float q2) {
    const bool in = q2 < 1.0f;
    const float wj = in ? 1.0f - q2 * std::sqrt(q2) : 0.0f;
    w += wj;
    mx += wj * dx; my += wj * dy; mz += wj * dz;
    sxx += wj * dx * dx; syy += wj * dy * dy; szz += wj * dz * dz;
    sxy += wj * dx * dy; sxz += wj * dx * dz; syz += wj * dy * dz;
    count += in ? 1.0f : 0.0f;
  }

  // [3][n] layout: {W, M}, {Sxx, Syy, Szz, Sxy}, {Sxz, Syz, count, 0}.
  SPHRAY_HD SPHRAY_FORCEINLINE void store(Float4* out, uint32_t n, uint32_t i) const {
    out[i] = {w, mx, my, mz};
    out[n + i] = {sxx, syy, szz, sxy};
    out[2 * size_t(n) + i] = {sxz, syz, count, 0.0f};
  }
  SPHRAY_HD SPHRAY_FORCEINLINE static CovarianceSums load(const Float4* in, uint32_t n, uint32_t i) {
    const Float4 a = in[i], b = in[n + i], c = in[2 * size_t(n) + i];
    CovarianceSums s;
    s.w = a.x; s.mx = a.y; s.my = a.z; s.mz = a.w;
    s.sxx = b.x; s.syy = b.y; s.szz = b.z; s.sxy = b.w;
    s.sxz = c.x; s.syz = c.y; s.count = c.z;
    return s;
  }
};

}  // namespace sphray
