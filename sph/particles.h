// Views of the solver's particle arrays as its kernels take them: grouped,
// and const where a kernel only reads, so that a launch cannot pass one
// array where another belongs (a const view does not convert to a mutable
// one). The solver makes each view in one place (solver_impl.inl).
#pragma once

#include <cstdint>

#include "core/vec.h"

namespace sphray {

// The fluid particles' state, in one sorted order.
struct ParticleArrays {
  Float4* pos;       // x, y, z, density
  Float4* vel;       // vx, vy, vz, -
  Float4* flow;      // u (predicted kicked velocity), p / rho^2
  uint32_t* id;      // index in the initial particle list
  uint8_t* status;   // integrate.h
  float* presence;   // [6][n]; null when there is none
  Float4* covariance = nullptr;  // [3][n] (sph/covariance.h); null when there is none
};
struct ConstParticleArrays {
  const Float4* pos;
  const Float4* vel;
  const Float4* flow;
  const uint32_t* id;
  const uint8_t* status;
  const float* presence;
  const Float4* covariance = nullptr;
};

// The sorted fluid as the neighbour loops read it.
struct FluidIn {
  const uint32_t* offsets;  // slab table (nsearch/grid.h)
  const Float4* pos_rho;    // x, y, z, density
  const Float4* flow;       // u, p / rho^2
};

// What the pair loop left per fluid particle, as integration reads it.
struct PairIn {
  const Float4* accel;      // ax, ay, az, R (interaction.h)
  const Float4* rate_grad;  // G, -
};

}  // namespace sphray
