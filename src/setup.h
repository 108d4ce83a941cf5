// From a validated scene to the solver's initial state: SPH parameters, the
// fluid lattice (hydrostatic initial density), wall particles and the grid.
#pragma once

#include <cstddef>

#include "scene.h"
#include "solver.h"

namespace sphray {

struct SceneSize {
  size_t fluid = 0, boundary = 0, cells = 0;
  int boundary_layers = 0;
  GridGeom grid{};
  size_t bytes = 0;  // estimated memory of the solver's buffers
};

SphParams make_params(const Scene& s);
// One presence lobe (cuda/sph/interaction.h) of a particle inside a full cubic
// lattice of spacing dx: the value that presence is normalised by.
double presence_lobe_on_lattice(const SmoothingKernel<double>& k, double dx);
SceneSize measure_scene(const Scene& s);  // counts only; generates nothing
SolverInput make_solver_input(const Scene& s, PresenceMode presence);

// Throws SceneError when the scene (with its density field when `field`)
// would need more memory than `backend` has free.
void check_fits(const Scene& s, Backend backend, bool field = false);

}  // namespace sphray
