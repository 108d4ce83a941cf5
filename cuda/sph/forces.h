// Forces stage: symmetric pressure gradient with the Tait equation of state,
// Monaghan (1992) artificial viscosity, gravity, and wall forces from boundary
// particles that carry the extrapolated wall pressure p_w of Adami et al.
// (2012; boundary.h) in the same symmetric form, with m_w = rho_w V_w.
// Walls are viscous (the artificial viscosity against a wall at rest, as in
// DualSPHysics) except the faces a scene declares free-slip (per-particle
// coefficient 0). Walls only push: negative pressures are clamped in the wall
// term, so tension cannot glue liquid to a wall.
#pragma once

#include <cstdint>

#include "boundary.h"
#include "neighbours.h"

namespace sphray {

// Direct: the launch for the particles whose pair masks overflowed (neighbours.h).
template <bool Direct = false>
struct Acceleration {
  SphParams prm;
  GridGeom grid;
  const uint32_t* fluid_offsets;  // slab tables (grid.h)
  const Float4* pos_rho;
  const Float4* vel;
  const uint32_t* boundary_offsets;
  const Float4* boundary;
  const WallState* wall;        // boundary.h
  const float* boundary_alpha;  // artificial viscosity against each wall particle; 0 = free slip
  PairMask fluid_pairs, boundary_pairs;  // neighbours.h, built with the grid
  Float4* accel;                // out: ax, ay, az, -

  SPHRAY_HD void operator()(uint32_t i) const {
    if (masks_complete(fluid_pairs, boundary_pairs, i) == Direct) return;  // the other launch's particle
    const Float4 pi = pos_rho[i];
    const Vec3f xi = xyz(pi);
    const Float4 vel_i = vel[i];
    const Vec3f vi = xyz(vel_i);
    const float h = prm.kernel.h;
    const float support2 = prm.kernel.support() * prm.kernel.support();
    const float p_over_rho2_i = vel_i.w;  // pressure_term(rho_i), see params.h
    // Monaghan's eta^2 = 0.01 h^2 keeps mu finite for close pairs.
    const float eta2 = 0.01f * h * h;
    Vec3f a = {0.0f, 0.0f, 0.0f};

    for_each_pair<Direct>(grid, fluid_offsets, pos_rho, xi, support2, i, fluid_pairs, i, [&](uint32_t j, Float4 pj, Vec3f r, float r2) {
      const float dwr = prm.kernel.dW_over_r(r2 * inv_sqrt(r2));
      const Float4 vj = load(vel + j);
      float term = p_over_rho2_i + vj.w;
      const float vr = dot(vi - xyz(vj), r);
      if (vr < 0.0f) {  // mu / rho_mean with mu = h vr / (r^2 + eta^2), in one division
        term -= prm.viscosity_alpha * prm.speed_of_sound * fast_div(h * vr, (r2 + eta2) * (0.5f * (pi.w + pj.w)));
      }
      a -= (prm.particle_mass * term * dwr) * r;
    });

    const float p_wall_i = p_over_rho2_i > 0.0f ? p_over_rho2_i : 0.0f;
    for_each_pair<Direct>(grid, boundary_offsets, boundary, xi, support2, kNoSkip, boundary_pairs, i, [&](uint32_t b, Float4 pb, Vec3f r, float r2) {
      const WallState w = wall[b];
      const float rho_w = w.rho;
      float term = p_wall_i + w.p_over_rho2;
      const float vr = dot(vi, r);
      if (vr < 0.0f)
        term -= boundary_alpha[b] * prm.speed_of_sound * fast_div(h * vr, (r2 + eta2) * (0.5f * (pi.w + rho_w)));
      a -= (rho_w * pb.w * term * prm.kernel.dW_over_r(r2 * inv_sqrt(r2))) * r;
    });

    a += prm.gravity;
    accel[i] = {a.x, a.y, a.z, 0.0f};
  }
};

}  // namespace sphray
