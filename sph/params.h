// SPH parameters, filled once from the scene (pipeline/setup.cpp) and
// passed by value to every kernel. Plain data: no pointers, no methods that allocate.
#pragma once

#include <cmath>
#include <cstdint>

#include "core/vec.h"
#include "eos.h"
#include "kernel.h"

namespace sphray {

struct SphParams {
  SmoothingKernel<float> kernel;
  float particle_mass;      // kg, rest_density * spacing^3
  float rest_density;       // rho0 [kg/m^3]
  float speed_of_sound;     // c0 [m/s]
  float tait_b;             // B = c0^2 rho0 / gamma [Pa] (eos.h)
  float viscosity_alpha;    // Monaghan (1992) artificial viscosity, dimensionless
  float density_diffusion;  // delta of Molteni & Colagrossi (2009), dimensionless
  Vec3f gravity;            // [m/s^2]
  float spacing;            // initial particle spacing dx [m]
  Aabb tank;                // fluid side of the tank walls [m]
  bool open_top;            // no lid: particles may leave through the top and are removed
  float presence_scale;     // 1 / (2 K), K = one presence lobe of a particle inside a full lattice (interaction.h)
};

// The pressure of a particle at density rho (eos.h).
SPHRAY_HD SPHRAY_FORCEINLINE float tait_pressure(const SphParams& p, float rho) {
  return tait_pressure(p.tait_b, p.rest_density, rho);
}

// p / rho^2, the pressure term of the momentum equation. Each particle keeps it
// in the w of what the pair loop gathers (flow.w, written when its density
// changes), so the loop reads it with the velocity it loads anyway instead of
// evaluating Tait per neighbour.
SPHRAY_HD SPHRAY_FORCEINLINE float pressure_term(const SphParams& p, float rho) {
  return tait_pressure(p, rho) / (rho * rho);
}

// a / b where a few ulps do not matter (particle volumes, viscosity): the GPU's
// approximate division (reciprocal + multiply, 2 ulp) instead of the IEEE
// sequence, flushing subnormals (no density, volume or distance here is
// one): __fdividef without the flush also scales subnormal operands, four
// more instructions per call.
SPHRAY_HD SPHRAY_FORCEINLINE float fast_div(float a, float b) {
#if defined(__CUDA_ARCH__)
  float q;
  asm("div.approx.ftz.f32 %0, %1, %2;" : "=f"(q) : "f"(a), "f"(b));
  return q;
#else
  return a / b;
#endif
}

// Projects x into the tank (the top stays open where the tank has none),
// `margin` [m] inside its walls.
SPHRAY_HD SPHRAY_FORCEINLINE Vec3f inside_tank(const SphParams& prm, Vec3f x, float margin = 0.0f) {
  x.x = std::fmin(std::fmax(x.x, prm.tank.min.x + margin), prm.tank.max.x - margin);
  x.y = std::fmin(std::fmax(x.y, prm.tank.min.y + margin), prm.tank.max.y - margin);
  x.z = std::fmax(x.z, prm.tank.min.z + margin);
  if (!prm.open_top) x.z = std::fmin(x.z, prm.tank.max.z - margin);
  return x;
}

}  // namespace sphray
