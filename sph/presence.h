// The six presence lobes of a particle from its neighbour sums (the
// definition is in interaction.h): per axis a, G_a = sum_j m (dW/dr / r) r_a
// and U_a = sum_j m (dW/dr / r) |r_a|, scaled by s = 1 / (2 K rho_i). Each
// solver's neighbour loop accumulates the sums with its own kernel and calls
// this to write them. PBF and DFSPH weigh each neighbour by the rest volume
// m / rho0 instead: their density is a kernel sum, which falls to about 0.7
// rho0 at a free surface, and m / rho_i there counted a flat surface's
// lateral neighbours as a full lattice (lateral lobes of 1 instead of 0.83
// with their kernels, tests/test_presence.cpp). WCSPH's density is integrated and stays
// near rho0 at a surface.
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

// The neighbour sums of the lobes as a loop gathers them, with the weight
// v_dwr = V_j (dW/dr / r) of each neighbour at offset r = x_i - x_j.
struct PresenceSums {
  Vec3f grad = {0.0f, 0.0f, 0.0f};
  float ux = 0.0f, uy = 0.0f, uz = 0.0f;
  SPHRAY_HD SPHRAY_FORCEINLINE void add(float v_dwr, Vec3f r) {
    grad += v_dwr * r;
    ux += v_dwr * std::fabs(r.x);
    uy += v_dwr * std::fabs(r.y);
    uz += v_dwr * std::fabs(r.z);
  }
  SPHRAY_HD SPHRAY_FORCEINLINE void write(float* presence, uint32_t n, uint32_t i, float s) const {
    write_presence_lobes(presence, n, i, s, grad, ux, uy, uz);
  }
};

}  // namespace sphray
