// SPH parameters, filled and validated once from the scene (src/scene.cpp) and
// passed by value to every kernel. Plain data: no pointers, no methods that allocate.
#pragma once

#include <cmath>
#include <cstdint>

#include "../common/vec.h"
#include "kernel.h"

namespace sphray {

// Four floats, 16-byte aligned, so one load fetches a particle's state on the GPU.
struct alignas(16) Float4 {
  float x, y, z, w;
};

SPHRAY_HD SPHRAY_FORCEINLINE Vec3f xyz(Float4 a) { return {a.x, a.y, a.z}; }

// Neighbour data is read-only within a stage: on the GPU, load it through the
// read-only data cache as one 16-byte load.
SPHRAY_HD SPHRAY_FORCEINLINE Float4 load(const Float4* p) {
#if defined(__CUDA_ARCH__)
  const float4 v = __ldg(reinterpret_cast<const float4*>(p));
  return {v.x, v.y, v.z, v.w};
#else
  return *p;
#endif
}

struct Aabb {
  Vec3f min, max;
};

struct SphParams {
  SmoothingKernel<float> kernel;
  float particle_mass;      // kg, rest_density * spacing^3
  float rest_density;       // rho0 [kg/m^3]
  float speed_of_sound;     // c0 [m/s]
  float tait_b;             // B = c0^2 rho0 / gamma [Pa]
  float viscosity_alpha;    // Monaghan (1992) artificial viscosity, dimensionless
  float density_diffusion;  // delta of Molteni & Colagrossi (2009), dimensionless
  Vec3f gravity;            // [m/s^2]
  float spacing;            // initial particle spacing dx [m]
  Aabb tank;                // fluid side of the tank walls [m]
  bool open_top;            // no lid: particles may leave through the top and are removed
  float presence_scale;     // 1 / (2 K), K = one presence lobe of a particle inside a full lattice (interaction.h)
};

// Tait equation of state, gamma = 7 (Monaghan 1994; Batchelor 1967).
SPHRAY_HD SPHRAY_FORCEINLINE float tait_pressure(const SphParams& p, float rho) {
  const float r = rho / p.rest_density;
  const float r2 = r * r, r4 = r2 * r2;
  return p.tait_b * (r4 * r2 * r - 1.0f);
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

// 1/sqrt(x): one special-function instruction on the GPU (flushing
// subnormals; rsqrtf without the flush scales them, four more instructions).
SPHRAY_HD SPHRAY_FORCEINLINE float inv_sqrt(float x) {
#if defined(__CUDA_ARCH__)
  float y;
  asm("rsqrt.approx.ftz.f32 %0, %1;" : "=f"(y) : "f"(x));
  return y;
#else
  return 1.0f / std::sqrt(x);
#endif
}

}  // namespace sphray
