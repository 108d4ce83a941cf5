// CUDA build of the SPH solver: the shared implementation on the CUDA backend.
#include "../backend/cuda.cuh"
#include "stages.h"

#define SPHRAY_BK cuda_backend
namespace sphray::cuda_backend {
#include "solver_impl.inl"
}  // namespace sphray::cuda_backend

namespace sphray {

bool cuda_available() {
  int count = 0;
  return cudaGetDeviceCount(&count) == cudaSuccess && count > 0;
}

std::string cuda_device_name() {
  if (!cuda_available()) return {};
  cudaDeviceProp prop{};
  SPHRAY_CUDA_CHECK(cudaGetDeviceProperties(&prop, 0));
  return prop.name;
}

size_t cuda_free_memory() {
  if (!cuda_available()) return 0;
  size_t free_b = 0, total_b = 0;
  SPHRAY_CUDA_CHECK(cudaMemGetInfo(&free_b, &total_b));
  return free_b;
}

std::unique_ptr<Solver> make_cuda_solver(const SolverInput& in) {
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
  return std::make_unique<cuda_backend::SolverImpl>(in);
}

GridBuild build_grid_cuda(const GridGeom& g, const std::vector<Vec3f>& points) {
  if (!cuda_available()) throw std::runtime_error("the CUDA backend was asked for, but no CUDA device is present");
  return cuda_backend::build_grid_impl(g, points);
}

PairMaskBuild build_pair_masks_cuda(const GridGeom& g, const std::vector<Vec3f>& points, float radius, uint32_t capacity,
                                    const std::vector<Vec3f>* queries, bool tensor_tiles) {
  if (!cuda_available()) throw std::runtime_error("the CUDA backend was asked for, but no CUDA device is present");
  return cuda_backend::build_pair_masks_impl(g, points, radius, capacity, queries, tensor_tiles);
}

}  // namespace sphray
