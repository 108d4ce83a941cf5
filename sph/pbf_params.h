// The constants of the position-based fluids solver (pbf.h), as its kernels
// take them: plain data, filled once from the scene's "pbf" section.
#pragma once

#include "pbf_kernel.h"

namespace sphray {

// The PBF solver's constants, filled once from the scene (pipeline/setup.cpp,
// make_pbf_params) and passed by value to its kernels.
struct PbfParams {
  PbfKernel<float> kernel;
  float volume;          // m / rho0 [m^3]: the particle mass over rest density
  float epsilon;         // constraint relaxation [m^2]
  float scorr_coef;      // k / G0 [m^2]: s_corr = -scorr_coef (W / W(dq))^n
  float inv_w_dq;        // 1 / W(dq)
  int scorr_n;           // exponent n of s_corr
  // [m] the largest correction of one particle in one iteration; 0: none.
  // A constraint that asks for more is an impact spike (a particle driven
  // into a compressed crowd), and a correction of a spacing in one step comes
  // back as a speed of dx / dt: the dam break's wave threw single particles
  // at 20-50 m/s where it hits the far wall. Jacobi carries a correction
  // about one support per iteration anyway; the rest waits for the next.
  float max_correction;
  float wall_margin;     // [m] the projection into the tank keeps this far inside its walls
  float xsph;            // XSPH viscosity c
  float vorticity;       // [m/s] vorticity confinement epsilon; 0: off
  float presence_scale;  // 1 / (2 K) with this kernel (interaction.h)
  float speed_floor;     // [m/s] the CFL's speed is at least this (ChooseFlowStep)
  float max_dt_depth;    // [s] the step at which the liquid's depth compresses by pbf.depth_error (ChooseFlowStep)
  float step_error;      // mean compression the steps after the first are sized to; 0: max_dt_depth throughout
  float step_error_flow; // ... while the largest speed is above flow_speed; 0: step_error throughout
  float flow_speed;      // [m/s] pbf.flow_speed x speed_floor
  int iterations;        // constraint iterations per step
  float tolerance;       // mean density error that ends the iterations early; 0: off
  // The wall images as mirrored particles (pbf.images "mirrored"): each
  // carries its original's lambda into the correction, counts in the
  // constraint's denominator and takes part in XSPH with its original's
  // velocity reflected, so that a free-slip wall acts as the liquid mirrored
  // across it; false: static wall particles (lambda_i only, no XSPH).
  bool mirrored_images;
  // The weights of lambda in the iterations of a step taken at rest (the
  // largest speed at most flow_speed; pbf.rest_weights, pbf_weights.h):
  // iteration k's is rest_weight[k % rest_weights]; 0 weights: lambda as is.
  static constexpr int kRestWeights = 8;
  int rest_weights;
  float rest_weight[kRestWeights];
};

}  // namespace sphray
