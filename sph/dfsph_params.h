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
  float max_dt_viscous;  // [s] the explicit viscosity's stability limit, 2 / (nu lambda), lambda its largest decay rate beside a wall (setup.cpp)
  float wall_margin;     // [m] the projection into the tank keeps this far inside its walls
  // A particle with fewer neighbours (wall images included) than this is at
  // a free surface or alone: the divergence solve leaves its density rate
  // alone, as SPlisHSPlasH does, since a surface particle expanding into the
  // air is no error to correct (and correcting it pulls the surface in).
  float sparse_neighbours;
  // The relaxed Jacobi iteration's weight w of both solves (dfsph.h,
  // DfsphUpdate): SPlisHSPlasH's 0.5, or kJacobiTop / p where the
  // kernel's lattice spectrum reaches p > 2 kJacobiTop (lattice.h,
  // lattice_spectrum_bound). A mode of eigenvalue p of D^-1 A is left at
  // 1 - w p by an iteration and grows past w p = 2: the cubic spline's p
  // reaches 3.04 at the default support of 2.1 spacings (w p = 1.52) and 4
  // at 2.44 spacings, Wendland C2's 4 at 2.55, beyond which 0.5 would let
  // the fastest modes grow. kJacobiTop keeps
  // the default's margin for a disordered liquid, whose modes reach
  // 1.1-1.15 p (pbf_weights.h): 1.6 x 1.15 = 1.84 < 2.
  static constexpr double kJacobiTop = 1.6;
  float jacobi_weight;
  float tolerance;             // mean compression that ends the pressure solve [share of rho0]
  float divergence_tolerance;  // mean density change per step that ends the divergence solve
  int min_iterations, max_iterations, max_divergence_iterations;
};

}  // namespace sphray
