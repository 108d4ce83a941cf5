// CUDA build of the BVH (bvh_build.inl).
#include "core/launch_cuda.cuh"
#include "core/atomics.h"
#include "bvh.h"

namespace sphray::cuda_backend {
#include "bvh_build.inl"
}  // namespace sphray::cuda_backend

namespace sphray {

std::unique_ptr<Bvh> make_cuda_bvh(const std::vector<Vec3f>& vertices, const std::vector<uint32_t>& indices) {
  return std::make_unique<cuda_backend::BvhImpl>(vertices, indices);
}

}  // namespace sphray
