// The kernels of position-based fluids (Macklin & Mueller 2013, after Mueller
// et al. 2003): poly6 for density, the spiky gradient for the constraint
// gradients, both with support s. Templated on the scalar so the tests check
// them in double.
#pragma once

#include <cmath>

#include "core/hd.h"
#include "core/vec.h"

namespace sphray {

template <class T>
struct PbfKernel {
  T s;        // support radius [m]
  T poly6;    // 315 / (64 pi s^9)
  T spiky;    // -45 / (pi s^6): dW/dr = spiky (s - r)^2

  static PbfKernel make(T support) {
    const T pi = T(3.14159265358979323846);
    const T s3 = support * support * support;
    return {support, T(315) / (T(64) * pi * s3 * s3 * s3), T(-45) / (pi * s3 * s3)};
  }

  // Poly6 at squared distance r2.
  SPHRAY_HD SPHRAY_FORCEINLINE T W(T r2) const {
    const T a = s * s - r2;
    return a > T(0) ? poly6 * a * a * a : T(0);
  }
  // W / poly6 = (s^2 - r^2)^3, 0 beyond the support: for a neighbour sum
  // that multiplies by poly6 (and the volume) once, after its loop.
  SPHRAY_HD SPHRAY_FORCEINLINE T W_over_poly6(T r2) const {
    T a = s * s - r2;
    a = a > T(0) ? a : T(0);
    return a * a * a;
  }
  // The spiky kernel's dW/dr divided by r, so that grad W = r_vec * dW_over_r.
  // Zero at r = 0, where the direction is undefined (coincident particles
  // exert nothing on each other rather than a NaN).
  SPHRAY_HD SPHRAY_FORCEINLINE T dW_over_r(T r) const {
    if (r >= s || r <= T(0)) return T(0);
    const T a = s - r;
    return spiky * a * a / r;
  }
  // dW_over_r at the squared distance r2, for the neighbour loops: r and
  // 1 / r from one reciprocal square root (inv_sqrt: one instruction on the
  // GPU) instead of a square root and a division, each a multi-instruction
  // IEEE sequence; selects, no branch. The same values as dW_over_r to a few
  // ulps (tests/test_pbf.cpp); zero at r2 = 0 and below the smallest normal
  // float, where inv_sqrt (flushing) gives no direction.
  SPHRAY_HD SPHRAY_FORCEINLINE T dW_over_r_sq(T r2) const { return scaled_dW_over_r_sq(r2, spiky); }
  // c dW_over_r_sq(r2) / spiky for a constant c_spiky = c spiky that the
  // caller folds once (the particle volume: one multiply fewer per neighbour).
  SPHRAY_HD SPHRAY_FORCEINLINE T scaled_dW_over_r_sq(T r2, T c_spiky) const {
    const T inv = inv_sqrt_or_zero(r2);
    const T r = r2 * inv;
    const T a = r < s ? s - r : T(0);
    return c_spiky * a * a * inv;
  }
  SPHRAY_HD SPHRAY_FORCEINLINE T support() const { return s; }
};

}  // namespace sphray
