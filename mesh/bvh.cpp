// CPU build of the BVH (bvh_build.inl) and the backend choice.
#include "core/launch_cpu.h"
#include "core/atomics.h"
#include "bvh.h"

namespace sphray::cpu_backend {
#include "bvh_build.inl"
}  // namespace sphray::cpu_backend

namespace sphray {

std::unique_ptr<Bvh> make_cpu_bvh(const std::vector<Vec3f>& vertices, const std::vector<uint32_t>& indices) {
  return std::make_unique<cpu_backend::BvhImpl>(vertices, indices);
}

std::unique_ptr<Bvh> make_bvh(Backend b, const std::vector<Vec3f>& vertices, const std::vector<uint32_t>& indices) {
  return b == Backend::Cuda ? make_cuda_bvh(vertices, indices) : make_cpu_bvh(vertices, indices);
}

#if !defined(SPHRAY_HAVE_CUDA)
std::unique_ptr<Bvh> make_cuda_bvh(const std::vector<Vec3f>&, const std::vector<uint32_t>&) {
  throw std::runtime_error("this build of sphray has no CUDA backend");
}
#endif

}  // namespace sphray
