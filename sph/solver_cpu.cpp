// CPU build of the SPH solvers (WCSPH, PBF and DFSPH): the shared implementations on the OpenMP backend.
#include "core/launch_cpu.h"
#include "stages.h"

#define SPHRAY_BK cpu_backend
namespace sphray::cpu_backend {
#include "solver_impl.inl"
#include "flow_solver.inl"
#include "pbf_solver.inl"
#include "dfsph_solver.inl"
}  // namespace sphray::cpu_backend

namespace sphray {

std::unique_ptr<Solver> make_cpu_solver(const SolverInput& in) {
  if (in.kind == SolverKind::Pbf) return std::make_unique<cpu_backend::PbfSolverImpl>(in);
  if (in.kind == SolverKind::Dfsph) return std::make_unique<cpu_backend::DfsphSolverImpl>(in);
  return std::make_unique<cpu_backend::SolverImpl>(in);
}

}  // namespace sphray
