#include "nsearch_probe.h"

namespace sphray {

GridBuild build_grid_cpu(const GridGeom& g, const std::vector<Vec3f>& points);
PairMaskBuild build_pair_masks_cpu(const GridGeom& g, const std::vector<Vec3f>& points, float radius, uint32_t capacity,
                                   const std::vector<Vec3f>* queries);
PartitionBuild partition_three_cpu(const std::vector<uint8_t>& classes);
#if defined(SPHRAY_HAVE_CUDA)
GridBuild build_grid_cuda(const GridGeom& g, const std::vector<Vec3f>& points);
PairMaskBuild build_pair_masks_cuda(const GridGeom& g, const std::vector<Vec3f>& points, float radius, uint32_t capacity,
                                    const std::vector<Vec3f>* queries, bool tensor_tiles);
PartitionBuild partition_three_cuda(const std::vector<uint8_t>& classes);
#else
GridBuild build_grid_cuda(const GridGeom&, const std::vector<Vec3f>&) { throw_no_cuda(); }
PairMaskBuild build_pair_masks_cuda(const GridGeom&, const std::vector<Vec3f>&, float, uint32_t,
                                    const std::vector<Vec3f>*, bool) {
  throw_no_cuda();
}
PartitionBuild partition_three_cuda(const std::vector<uint8_t>&) { throw_no_cuda(); }
#endif

GridBuild build_grid(Backend b, const GridGeom& g, const std::vector<Vec3f>& points) {
  return b == Backend::Cuda ? build_grid_cuda(g, points) : build_grid_cpu(g, points);
}

PairMaskBuild build_pair_masks(Backend b, const GridGeom& g, const std::vector<Vec3f>& points, float radius,
                               uint32_t capacity, const std::vector<Vec3f>* queries, bool tensor_tiles) {
  return b == Backend::Cuda ? build_pair_masks_cuda(g, points, radius, capacity, queries, tensor_tiles)
                            : build_pair_masks_cpu(g, points, radius, capacity, queries);
}

PartitionBuild partition_three(Backend b, const std::vector<uint8_t>& classes) {
  return b == Backend::Cuda ? partition_three_cuda(classes) : partition_three_cpu(classes);
}

}  // namespace sphray
