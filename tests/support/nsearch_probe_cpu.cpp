// The neighbour-search probes on the CPU backend.
#include <algorithm>

#include "core/launch_cpu.h"
#include "nsearch/pair_masks.h"
#include "nsearch_probe.h"

namespace sphray::cpu_backend {
#include "nsearch/sort.inl"
#include "nsearch_probe.inl"
}  // namespace sphray::cpu_backend

namespace sphray {

GridBuild build_grid_cpu(const GridGeom& g, const std::vector<Vec3f>& points) {
  return cpu_backend::build_grid_impl(g, points);
}

PairMaskBuild build_pair_masks_cpu(const GridGeom& g, const std::vector<Vec3f>& points, float radius, uint32_t capacity,
                                   const std::vector<Vec3f>* queries) {
  return cpu_backend::build_pair_masks_impl(g, points, radius, capacity, queries);
}

PartitionBuild partition_three_cpu(const std::vector<uint8_t>& classes) {
  return cpu_backend::partition_three_impl(classes);
}

}  // namespace sphray
