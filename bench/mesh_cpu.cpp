// bench mesh's probe on the CPU backend.
#include "core/launch_cpu.h"
#include "bench/mesh.h"
#include "sph/obstacles.h"

namespace sphray::cpu_backend {
#include "mesh_probe.inl"
}  // namespace sphray::cpu_backend

namespace sphray {

std::unique_ptr<MeshProbe> make_cpu_mesh_probe() { return std::make_unique<cpu_backend::MeshProbeImpl>(); }

#if !defined(SPHRAY_HAVE_CUDA)
std::unique_ptr<MeshProbe> make_cuda_mesh_probe() { throw std::runtime_error("this build of sphray has no CUDA backend"); }
#endif

}  // namespace sphray
