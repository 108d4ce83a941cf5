// The scene's "sph" section (docs/scenes.md): what the SPH solver is asked
// for, with its defaults in one place. Read and validated by read_sph_config;
// turned into the kernels' SphParams by the pipeline (pipeline/setup.h).
#pragma once

#include "core/config_reader.h"
#include "kernel.h"

namespace sphray {

struct SphConfig {
  double spacing = 0;            // dx [m], required
  double rest_density = 1000;    // [kg/m^3]
  double speed_of_sound = 0;     // [m/s], 0 = auto (10x the flow speed the scene can reach)
  double smoothing_ratio = 2.0;  // h / dx (DualSPHysics uses 1.2 sqrt(3) = 2.08 in 3D)
  KernelType kernel = KernelType::WendlandC2;
  double viscosity_alpha = 0.02;
  double wall_viscosity_alpha = -1;  // against viscous walls; < 0: viscosity_alpha
  double density_diffusion = 0.1;
  double cfl = 0.25;
  int boundary_layers = 0;  // 0 = auto: enough to cover the support radius
  bool presence = false;    // presence on every step (studies); otherwise only where a stage needs it

  // The smoothing kernel of this section, and its support radius [m].
  SmoothingKernel<double> smoothing_kernel() const {
    return SmoothingKernel<double>::make(kernel, smoothing_ratio * spacing);
  }
  double support_radius() const { return smoothing_kernel().support(); }
  // The automatic number of wall particle layers: enough to cover the
  // kernel's support (rounded up), so that a particle at a wall face finds
  // its kernel full. Fewer (boundary_layers) leave part of it empty near walls.
  int auto_boundary_layers() const;
  // boundary_layers, or the automatic number.
  int wall_layers() const { return boundary_layers > 0 ? boundary_layers : auto_boundary_layers(); }
};

// The "sph" section; the speed of sound against the scene's flow is checked
// by the scene (io/scene.cpp), which knows the tank and the liquid.
SphConfig read_sph_config(const ConfigReader& r);

}  // namespace sphray
