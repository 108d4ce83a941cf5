// Density stage: continuity equation with the delta-SPH density-diffusion term
// of Molteni & Colagrossi (2009, eq. 8) with the hydrostatic correction of
// Fourtakas et al. (2019, "DDT" of DualSPHysics 5): only the departure from the
// hydrostatic density difference diffuses, otherwise the one-sided free surface
// pumps density upward and a tank at rest loses its hydrostatic profile. In the same
// neighbour loop, the six-direction "particle presence" of Yasuda, Harada &
// Kawaguchi (shared/papers, sec. 4.2.3).
//
// Presence, as defined here: for each signed axis direction d,
//   P_d = min(1, (1 / K) * sum_{j in half-space d} V_j (-dW/dr) |cos(r_ij, d)|)
// with K the same sum for a particle inside a full cubic lattice of the
// scene's spacing (setup.cpp, presence_lobe_on_lattice): a particle deep in the
// liquid reads ~1 in all six directions, a free-surface particle 0 toward the
// air (~1 into the liquid, in between sideways) and an isolated one 0; the
// particle itself weighs nothing (r = 0). Per neighbour that is
// V_j (-dW/dr / r) |r_a|, and V_j (-dW/dr / r) is the weight the diffusion term
// computes anyway, so presence costs two FMAs per axis and neighbour (Yasuda
// et al.'s own weight is an ad hoc k / (x / y^2); any smooth lobe with these
// three properties serves the field builder). Only liquid counts: walls are not liquid.
#pragma once

#include <cstdint>

#include "neighbours.h"

namespace sphray {

// Direct: the launch for the particles whose pair masks overflowed (neighbours.h).
template <bool WithPresence, bool Direct = false>
struct DensityRate {
  SphParams prm;
  GridGeom grid;
  const uint32_t* fluid_offsets;  // slab tables (grid.h)
  const Float4* pos_rho;  // sorted fluid: x, y, z, density
  const Float4* vel;      // sorted fluid: vx, vy, vz, -
  const uint32_t* boundary_offsets;
  const Float4* boundary;  // sorted boundary: x, y, z, volume
  PairMask fluid_pairs, boundary_pairs;  // neighbours.h, built with the grid
  float* drho_dt;          // out
  float* presence;         // out, [6][n] direction-major (+x,-x,+y,-y,+z,-z); null without presence
  uint32_t n;

  SPHRAY_HD void operator()(uint32_t i) const {
    if (masks_complete(fluid_pairs, boundary_pairs, i) == Direct) return;  // the other launch's particle
    const Float4 pi = pos_rho[i];
    const Vec3f xi = xyz(pi);
    const Vec3f vi = xyz(vel[i]);
    const float support2 = prm.kernel.support() * prm.kernel.support();
    const float diffusion = 2.0f * prm.density_diffusion * prm.kernel.h * prm.speed_of_sound;
    // Linearised Tait: hydrostatic rho_j - rho_i = rho0 g.(x_j - x_i) / c0^2.
    const float hydro = prm.rest_density / (prm.speed_of_sound * prm.speed_of_sound);
    float rate = 0.0f;
    // Presence lobes in registers (named scalars, not an indexed array, so the
    // GPU keeps them out of local memory). Per axis, s = sum w r_a and
    // u = sum w |r_a| give both half-space lobes: +a = (u - s) / 2 (neighbours
    // with r_a < 0 lie toward +a), -a = (u + s) / 2. Two FMAs per axis.
    float sx = 0, sy = 0, sz = 0, ux = 0, uy = 0, uz = 0;

    for_each_pair<Direct>(grid, fluid_offsets, pos_rho, xi, support2, i, fluid_pairs, i, [&](uint32_t j, Float4 pj, Vec3f r, float r2) {
      const float dwr = prm.kernel.dW_over_r(r2 * inv_sqrt(r2));
      const float vol_j = fast_div(prm.particle_mass, pj.w);
      const float weight = -dwr * vol_j;  // V_j (-dW/dr / r) >= 0
      rate += prm.particle_mass * dot(vi - xyz(load(vel + j)), r) * dwr;
      rate += diffusion * ((pj.w - pi.w) + hydro * dot(prm.gravity, r)) * weight;
      if (WithPresence) {
        sx += weight * r.x; ux += weight * std::fabs(r.x);
        sy += weight * r.y; uy += weight * std::fabs(r.y);
        sz += weight * r.z; uz += weight * std::fabs(r.z);
      }
    });

    // Static walls (boundary particles of volume V_b, at rest): approaching a
    // wall compresses the particle (Adami et al. 2012, eq. 22 with v_w = 0).
    for_each_pair<Direct>(grid, boundary_offsets, boundary, xi, support2, kNoSkip, boundary_pairs, i, [&](uint32_t, Float4 pb, Vec3f r, float r2) {
      rate += pi.w * pb.w * dot(vi, r) * prm.kernel.dW_over_r(std::sqrt(r2));
    });

    drho_dt[i] = rate;
    if (WithPresence) {
      const float c = prm.presence_scale;  // (u -+ s) / 2, over the lattice lobe K
      presence[0 * n + i] = std::fmin(1.0f, std::fmax(0.0f, c * (ux - sx)));
      presence[1 * n + i] = std::fmin(1.0f, std::fmax(0.0f, c * (ux + sx)));
      presence[2 * n + i] = std::fmin(1.0f, std::fmax(0.0f, c * (uy - sy)));
      presence[3 * n + i] = std::fmin(1.0f, std::fmax(0.0f, c * (uy + sy)));
      presence[4 * n + i] = std::fmin(1.0f, std::fmax(0.0f, c * (uz - sz)));
      presence[5 * n + i] = std::fmin(1.0f, std::fmax(0.0f, c * (uz + sz)));
    }
  }
};

}  // namespace sphray
