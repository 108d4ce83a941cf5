// The liquid's physical constants, and Tait's equation of state of a weakly
// compressible liquid (Monaghan 1994, after Batchelor 1967):
// p = B ((rho / rho0)^gamma - 1), B = c0^2 rho0 / gamma, gamma = 7. In float
// on the device, in double for the initial state and the tests' references.
#pragma once

#include <cmath>

#include "core/hd.h"

namespace sphray {

constexpr int kTaitGamma = 7;
// [m/s^2]: a scene's gravity unless it gives one, and the g of the flow speed
// a scene without gravity is expected to reach (io/scene.h).
constexpr double kStandardGravity = 9.81;

// B [Pa] from the speed of sound c0 [m/s] and the rest density rho0 [kg/m^3].
template <class T>
SPHRAY_HD SPHRAY_FORCEINLINE T tait_b(T c0, T rho0) {
  return c0 * c0 * rho0 / T(kTaitGamma);
}

template <class T>
SPHRAY_HD SPHRAY_FORCEINLINE T tait_pressure(T b, T rho0, T rho) {
  const T r = rho / rho0;
  const T r2 = r * r, r4 = r2 * r2;
  return b * (r4 * r2 * r - T(1));
}

// The density at a pressure: the inverse of tait_pressure.
template <class T>
SPHRAY_HD SPHRAY_FORCEINLINE T tait_density(T b, T rho0, T pressure) {
  return rho0 * std::pow(T(1) + pressure / b, T(1) / T(kTaitGamma));
}

}  // namespace sphray
