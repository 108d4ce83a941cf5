// The constants of the divergence-free SPH solver (dfsph.h), as its kernels
// take them: plain data, filled once from the scene's "dfsph" section.
#pragma once

#include "kernel.h"

namespace sphray {

// The DFSPH solver's constants, filled once from the scene (pipeline/setup.cpp,
// make_dfsph_params) and passed by value to its kernels.
struct DfsphParams {
  SmoothingKernel<float> kernel;  // support dfsph.support spacings
  float volume;          // m / rho0 [m^3], calibrated so that a full lattice has the rest density
  float viscosity;       // 2 (d + 2) nu = 10 nu [m^2/s]; 0: no viscosity pass
  float viscosity_eta2;  // 0.01 h^2 [m^2]: keeps the viscous term finite at small r
  uint32_t no_slip_faces;  // bit 2a + side: the tank face is no-slip for the viscosity (-x, +x, -y, +y, -z, +z)
  float presence_scale;  // 1 / (2 K) with this kernel (interaction.h)
  float speed_floor;     // [m/s] the CFL's speed is at least this (ChooseFlowStep)
  float max_dt_viscous;  // [s] the explicit viscosity's stability limit, 0.125 h^2 / nu
  float wall_margin;     // [m] the projection into the tank keeps this far inside its walls
  // A particle with fewer neighbours (wall images included) than this is at
  // a free surface or alone: the divergence solve leaves its density rate
  // alone, as SPlisHSPlasH does, since a surface particle expanding into the
  // air is no error to correct (and correcting it pulls the surface in).
  float sparse_neighbours;
  float tolerance;             // mean compression that ends the pressure solve [share of rho0]
  float divergence_tolerance;  // mean density change per step that ends the divergence solve
  int min_iterations, max_iterations, max_divergence_iterations;
};

}  // namespace sphray
