// The neighbour-search probes on the CUDA backend.
#include "core/launch_cuda.cuh"
#include "nsearch/pair_masks.h"
#include "nsearch_probe.h"

namespace sphray::cuda_backend {
#include "nsearch/sort.inl"
#include "nsearch_probe.inl"
}  // namespace sphray::cuda_backend

namespace sphray {

GridBuild build_grid_cuda(const GridGeom& g, const std::vector<Vec3f>& points) {
  if (!cuda_available()) throw std::runtime_error("the CUDA backend was asked for, but no CUDA device is present");
  return cuda_backend::build_grid_impl(g, points);
}

PairMaskBuild build_pair_masks_cuda(const GridGeom& g, const std::vector<Vec3f>& points, float radius, uint32_t capacity,
                                    const std::vector<Vec3f>* queries, bool tensor_tiles) {
  if (!cuda_available()) throw std::runtime_error("the CUDA backend was asked for, but no CUDA device is present");
  return cuda_backend::build_pair_masks_impl(g, points, radius, capacity, queries, tensor_tiles);
}

PartitionBuild partition_three_cuda(const std::vector<uint8_t>& classes) {
  if (!cuda_available()) throw std::runtime_error("the CUDA backend was asked for, but no CUDA device is present");
  return cuda_backend::partition_three_impl(classes);
}

}  // namespace sphray
