// CUDA build of the SPH solvers (WCSPH, PBF and DFSPH): the shared implementations on the CUDA backend.
#include "core/launch_cuda.cuh"
#include "stages.h"

#define SPHRAY_BK cuda_backend
namespace sphray::cuda_backend {
#include "solver_impl.inl"
#include "flow_solver.inl"
#include "pbf_solver.inl"
#include "dfsph_solver.inl"
#include "skin_impl.inl"
}  // namespace sphray::cuda_backend

namespace sphray {

namespace {

std::unique_ptr<Solver> make_cuda_fluid_solver(const SolverInput& in) {
  if (!cuda_available()) throw std::runtime_error("the CUDA backend was asked for, but no CUDA device is present");
  // The export's snapshots in page-locked memory: their copies off the device
  // run about twice as fast (host_memory.h). Installed once per process.
  static const bool pinned = [] {
    set_pinned_provider({[](size_t bytes) -> void* {
                           void* p = nullptr;
                           if (cudaMallocHost(&p, bytes) == cudaSuccess) return p;
                           cudaGetLastError();  // not left for the next launch check to find
                           return nullptr;
                         },
                         [](void* p) { cudaFreeHost(p); }});
    return true;
  }();
  (void)pinned;
  if (in.kind == SolverKind::Pbf) return std::make_unique<cuda_backend::PbfSolverImpl>(in);
  if (in.kind == SolverKind::Dfsph) return std::make_unique<cuda_backend::DfsphSolverImpl>(in);
  return std::make_unique<cuda_backend::SolverImpl>(in);
}

}  // namespace

std::unique_ptr<SkinSet> make_cuda_skin_set(std::vector<SkinGeometry> geo, const SphParams& prm) {
  return std::make_unique<cuda_backend::SkinSetImpl>(std::move(geo), prm);
}

std::unique_ptr<Solver> make_cuda_solver(const SolverInput& in) {
  return with_skins(make_cuda_fluid_solver(in), in.skins, in.params);
}

}  // namespace sphray
