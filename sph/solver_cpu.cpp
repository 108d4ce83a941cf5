// CPU build of the SPH solvers (WCSPH, PBF and DFSPH): the shared implementations on the OpenMP backend.
#include "core/launch_cpu.h"
#include "stages.h"

#define SPHRAY_BK cpu_backend
namespace sphray::cpu_backend {
#include "solver_impl.inl"
#include "flow_solver.inl"
#include "pbf_solver.inl"
#include "dfsph_solver.inl"
#include "skin_impl.inl"
}  // namespace sphray::cpu_backend

namespace sphray {

namespace {

std::unique_ptr<Solver> make_cpu_fluid_solver(const SolverInput& in) {
  if (in.kind == SolverKind::Pbf) return std::make_unique<cpu_backend::PbfSolverImpl>(in);
  if (in.kind == SolverKind::Dfsph) return std::make_unique<cpu_backend::DfsphSolverImpl>(in);
  return std::make_unique<cpu_backend::SolverImpl>(in);
}

}  // namespace

std::unique_ptr<SkinSet> make_cpu_skin_set(std::vector<SkinGeometry> geo, const SphParams& prm) {
  return std::make_unique<cpu_backend::SkinSetImpl>(std::move(geo), prm);
}

std::unique_ptr<Solver> make_cpu_solver(const SolverInput& in) {
  return with_skins(make_cpu_fluid_solver(in), in.skins, in.params);
}

}  // namespace sphray
