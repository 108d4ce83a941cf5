// bench mesh's probe on the CUDA backend.
#include "core/launch_cuda.cuh"
#include "bench/mesh.h"
#include "sph/obstacles.h"

namespace sphray::cuda_backend {
#include "mesh_probe.inl"
}  // namespace sphray::cuda_backend

namespace sphray {

std::unique_ptr<MeshProbe> make_cuda_mesh_probe() { return std::make_unique<cuda_backend::MeshProbeImpl>(); }

}  // namespace sphray
