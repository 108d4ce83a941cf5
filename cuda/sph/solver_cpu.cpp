// CPU build of the SPH solver: the shared implementation on the OpenMP backend.
#include "../backend/cpu.h"
#include "stages.h"

#define SPHRAY_BK cpu_backend
namespace sphray::cpu_backend {
#include "solver_impl.inl"
}  // namespace sphray::cpu_backend

namespace sphray {

std::unique_ptr<Solver> make_cpu_solver(const SolverInput& in) { return std::make_unique<cpu_backend::SolverImpl>(in); }

GridBuild build_grid_cpu(const GridGeom& g, const std::vector<Vec3f>& points) {
  return cpu_backend::build_grid_impl(g, points);
}

PairMaskBuild build_pair_masks_cpu(const GridGeom& g, const std::vector<Vec3f>& points, float radius, uint32_t capacity,
                                   const std::vector<Vec3f>* queries) {
  return cpu_backend::build_pair_masks_impl(g, points, radius, capacity, queries);
}

}  // namespace sphray
