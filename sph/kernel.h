// SPH smoothing kernels in 3D, support radius 2h, for host and device.
// Wendland C2: Wendland (1995), normalisation of Dehnen & Aly (2012), stable
// against pairing at any h/dx. Cubic spline: Monaghan & Lattanzio (1985).
// Templated on the scalar so tests evaluate the same formulas in double.
#pragma once

#include "core/hd.h"
#include "core/vec.h"

namespace sphray {

enum class KernelType : int { WendlandC2 = 0, CubicSpline = 1 };

template <class T>
struct SmoothingKernel {
  KernelType type;
  T h;      // smoothing length [m]; support radius is 2h
  T sigma;  // normalisation [1/m^3]
  // Precomputed so that the neighbour loops multiply instead of divide (an
  // IEEE division is a multi-instruction sequence on the GPU).
  T inv_h;     // 1 / h
  T grad_coef; // sigma / h^2 (times -5 for Wendland C2)
  T half_inv_h;  // 1 / (2h): Wendland's 1 - q/2 as one FMA (W_for, dW_over_r_for)

  static SmoothingKernel make(KernelType type, T h) {
    const T pi = T(3.14159265358979323846);
    T sigma = type == KernelType::WendlandC2 ? T(21) / (T(16) * pi * h * h * h) : T(1) / (pi * h * h * h);
    const T grad = sigma / (h * h) * (type == KernelType::WendlandC2 ? T(-5) : T(1));
    return {type, h, sigma, T(1) / h, grad, T(0.5) / h};
  }

  SPHRAY_HD SPHRAY_FORCEINLINE T support() const { return T(2) * h; }

  SPHRAY_HD SPHRAY_FORCEINLINE T W(T r) const {
    if (r >= support()) return T(0);  // on r, not q: r * inv_h can round below 2 at the support
    const T q = r * inv_h;
    if (type == KernelType::WendlandC2) {
      const T a = T(1) - T(0.5) * q;
      const T a2 = a * a;
      return sigma * a2 * a2 * (T(2) * q + T(1));
    }
    if (q < T(1)) return sigma * (T(1) - T(1.5) * q * q + T(0.75) * q * q * q);
    const T b = T(2) - q;
    return sigma * T(0.25) * b * b * b;
  }

  // dW/dr divided by r, so that grad_i W_ij = (x_i - x_j) * dW_over_r(r).
  // Finite at r -> 0 for both kernels, so coincident particles are harmless.
  SPHRAY_HD SPHRAY_FORCEINLINE T dW_over_r(T r) const {
    if (r >= support()) return T(0);  // on r, not q: r * inv_h can round below 2 at the support
    const T q = r * inv_h;
    if (type == KernelType::WendlandC2) {
      const T a = T(1) - T(0.5) * q;
      return grad_coef * a * a * a;  // -5 sigma a^3 / h^2
    }
    if (q < T(1)) return grad_coef * (T(-3) + T(2.25) * q);
    const T b = T(2) - q;
    return q > T(0) ? grad_coef * T(-0.75) * b * b / q : T(0);
  }

  // dW_over_r at the squared distance r2, for the neighbour loops: r and 1 / r
  // from one inv_sqrt (in float) instead of a square root and, for the cubic
  // spline's outer part, a division. The same values as dW_over_r to
  // rounding (tests/test_kernel.cpp); r2 below the smallest normal float
  // counts as r = 0.
  SPHRAY_HD SPHRAY_FORCEINLINE T dW_over_r_sq(T r2) const {
    const T inv = inv_sqrt_or_zero(r2);
    const T r = r2 * inv;
    if (!(r < support())) return T(0);
    const T q = r * inv_h;
    if (type == KernelType::WendlandC2) {
      const T a = T(1) - T(0.5) * q;
      return grad_coef * a * a * a;
    }
    if (q < T(1)) return grad_coef * (T(-3) + T(2.25) * q);
    const T b = T(2) - q;
    return grad_coef * T(-0.75) * b * b * h * inv;  // 1 / q = h / r
  }

  // W for a kernel type fixed at compile time, for the wall pressure
  // (boundary.h), as dW_over_r_for is for the pair loop. The same values as
  // W to rounding (tests/test_kernel.cpp).
  template <KernelType K>
  SPHRAY_HD SPHRAY_FORCEINLINE T W_for(T r) const {
    if constexpr (K == KernelType::WendlandC2) {
      const T a = r < support() ? T(1) - r * half_inv_h : T(0);
      const T a2 = a * a;
      return sigma * a2 * a2 * (T(2) * (r * inv_h) + T(1));
    } else {
      return W(r);
    }
  }

  // dW_over_r for a kernel type fixed at compile time, for the pair loop
  // (interaction.h): no branch on the type, and for Wendland C2 the support
  // test a select rather than a branch (9 instructions on the GPU instead of
  // 16, SASS; 1 - q/2 one FMA on r, 8). The same values as dW_over_r to
  // rounding (tests/test_kernel.cpp).
  template <KernelType K>
  SPHRAY_HD SPHRAY_FORCEINLINE T dW_over_r_for(T r) const {
    if constexpr (K == KernelType::WendlandC2) {
      const T a = r < support() ? T(1) - r * half_inv_h : T(0);
      return grad_coef * a * a * a;
    } else {
      return dW_over_r(r);
    }
  }
};

}  // namespace sphray
