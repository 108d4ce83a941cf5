// The six presence lobes of a particle from its neighbour sums (the
// definition is in interaction.h): per axis a, G_a = sum_j m (dW/dr / r) r_a
// and U_a = sum_j m (dW/dr / r) |r_a|, scaled by s = 1 / (2 K rho_i). Both
// solvers' neighbour loops accumulate the sums with their own kernel and call
// this to write them.
#pragma once

#include <cmath>
#include <cstdint>

#include "core/vec.h"

namespace sphray {

// presence is [6][n] direction-major (+x,-x,+y,-y,+z,-z).
SPHRAY_HD SPHRAY_FORCEINLINE void write_presence_lobes(float* presence, uint32_t n, uint32_t i, float s, Vec3f grad,
                                                       float ux, float uy, float uz) {
  presence[0 * n + i] = std::fmin(1.0f, std::fmax(0.0f, s * (grad.x - ux)));
  presence[1 * n + i] = std::fmin(1.0f, std::fmax(0.0f, -s * (grad.x + ux)));
  presence[2 * n + i] = std::fmin(1.0f, std::fmax(0.0f, s * (grad.y - uy)));
  presence[3 * n + i] = std::fmin(1.0f, std::fmax(0.0f, -s * (grad.y + uy)));
  presence[4 * n + i] = std::fmin(1.0f, std::fmax(0.0f, s * (grad.z - uz)));
  presence[5 * n + i] = std::fmin(1.0f, std::fmax(0.0f, -s * (grad.z + uz)));
}

}  // namespace sphray
