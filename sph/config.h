// The scene's "sph" section (docs/scenes.md): what the SPH solver is asked
// for, with its defaults in one place. Read and validated by read_sph_config;
// turned into the kernels' SphParams by the pipeline (pipeline/setup.h).
#pragma once

#include "core/config_reader.h"
#include "kernel.h"
#include "solver_kind.h"

namespace sphray {

// The scene's "pbf" section: the position-based fluids solver (pbf.h,
// docs/method.md). Read only when sph.solver is "pbf".
struct PbfConfig {
  int iterations = 3;         // constraint iterations per step
  double tolerance = 0;       // mean density error that ends the iterations early; 0: off
  double support = 2.1;       // kernel support [spacings]
  double relaxation = 0.1;    // eps of the constraint, as a share of sum |grad C|^2 in a full lattice
  double scorr_k = 0;         // s_corr strength, as a share of the lambda of a 100% compression (off: docs/method.md)
  double scorr_dq = 0.2;      // s_corr reference distance [supports]
  int scorr_n = 4;            // s_corr exponent
  double wall_margin = 0.1;   // [spacings] the projection into the tank keeps particles this far inside its walls (docs/method.md)
  bool mirrored_images = true;  // "images": the tank walls' images are the mirrored liquid ("mirrored") or static wall particles ("static")
  bool rest_chebyshev = true;   // "rest_weights": lambda weighted per iteration at rest ("chebyshev", pbf_weights.h) or as is ("uniform")
  double max_correction = 0.25;  // largest correction per particle and iteration [spacings]; 0: none
  double depth_error = 0.01;  // compression a column may keep between steps (the depth limit of dt); 0: no limit
  double step_error = 0.005;  // mean compression the steps after the first are sized to (ChooseFlowStep); 0: the depth limit throughout
  double step_error_flow = 0.01;  // the same while the largest speed is above flow_speed sqrt(g H) (at least step_error); 0: step_error throughout
  double flow_speed = 1.0;        // [sqrt(g H)] the speed above which a liquid is flowing (step_error_flow)
  double xsph = 0.3;          // XSPH viscosity c (the share of the neighbours' mean velocity difference per step)
  double vorticity = 0;       // vorticity confinement epsilon [m/s]; 0: off (docs/method.md)
};

// The scene's "dfsph" section: the divergence-free SPH solver (dfsph.h,
// docs/method.md). Read only when sph.solver is "dfsph".
struct DfsphConfig {
  double tolerance = 0.001;             // mean compression the pressure solve may leave [share of rho0]
  double divergence_tolerance = 0.001;  // mean density change per step the divergence solve may leave [share of rho0]
  int min_iterations = 2;               // pressure iterations at least
  int max_iterations = 100;             // pressure iterations at most
  int max_divergence_iterations = 100;  // divergence iterations at most (at least 1)
  KernelType kernel = KernelType::CubicSpline;
  double support = 2.1;                 // kernel support [spacings]
  double viscosity = -1;                // kinematic viscosity [m^2/s]; < 0: auto (docs/scenes.md)
  double wall_margin = 0.1;             // [spacings] the projection into the tank keeps particles this far inside its walls (docs/method.md)
};

struct SphConfig {
  SolverKind solver = SolverKind::Wcsph;
  double spacing = 0;            // dx [m], required
  double rest_density = 1000;    // [kg/m^3]
  double speed_of_sound = 0;     // [m/s], 0 = auto (10x the flow speed the scene can reach)
  double smoothing_ratio = 2.0;  // h / dx (DualSPHysics uses 1.2 sqrt(3) = 2.08 in 3D)
  KernelType kernel = KernelType::WendlandC2;
  double viscosity_alpha = 0.02;
  double wall_viscosity_alpha = -1;  // against viscous walls; < 0: viscosity_alpha
  double density_diffusion = 0.1;
  // WCSPH: dt = cfl h / (c0 + v_max) (and the force and viscous limits);
  // PBF and DFSPH: dt = cfl dx / v_max. The default depends on the solver.
  static constexpr double kWcsphCfl = 0.25, kPbfCfl = 1.0, kDfsphCfl = 0.4;
  double cfl = kWcsphCfl;
  int boundary_layers = 0;  // 0 = auto: enough to cover the support radius
  bool presence = false;    // presence on every step (studies); otherwise only where a stage needs it
  PbfConfig pbf;            // sph.solver "pbf"
  DfsphConfig dfsph;        // sph.solver "dfsph"

  // The smoothing kernel of this section (WCSPH), and its support radius [m].
  SmoothingKernel<double> smoothing_kernel() const {
    return SmoothingKernel<double>::make(kernel, smoothing_ratio * spacing);
  }
  double support_radius() const { return smoothing_kernel().support(); }
  // The automatic number of wall particle layers: enough to cover the
  // kernel's support (rounded up), so that a particle at a wall face finds
  // its kernel full. Fewer (boundary_layers) leave part of it empty near walls.
  int auto_boundary_layers() const;
  // boundary_layers, or the automatic number; none for PBF and DFSPH, whose
  // tank walls are its planes (mirror_walls.h).
  int wall_layers() const {
    if (incompressible(solver)) return 0;
    return boundary_layers > 0 ? boundary_layers : auto_boundary_layers();
  }
  // The layers of wall particles inside an obstacle's surface: WCSPH's
  // wall_layers(), and for PBF and DFSPH enough to cover their support.
  int mesh_wall_layers() const {
    switch (solver) {
      case SolverKind::Pbf: return int(std::ceil(pbf.support - 1e-9));
      case SolverKind::Dfsph: return int(std::ceil(dfsph.support - 1e-9));
      default: return wall_layers();
    }
  }
  // The neighbour grid's cell edge [m] (and with it the field's voxels): the
  // WCSPH support, or twice the PBF or DFSPH support, so that every solver's
  // grid has cells of about 4 spacings at its defaults and the field keeps
  // its voxel size whichever solver runs (PBF and DFSPH search only their
  // support within them).
  double grid_cell() const {
    switch (solver) {
      case SolverKind::Pbf: return 2.0 * pbf.support * spacing;
      case SolverKind::Dfsph: return 2.0 * dfsph.support * spacing;
      default: return support_radius();
    }
  }
};

// The "sph" section, and the "pbf" or "dfsph" section of the solver it
// runs; options of a solver the scene does not run are refused by name. The speed of
// sound against the scene's flow is checked by the scene (io/scene.cpp),
// which knows the tank and the liquid.
SphConfig read_sph_config(const ConfigReader& r, const ConfigReader& pbf, const ConfigReader& dfsph);

}  // namespace sphray
