// The neighbour search run alone over given points, on either backend, with
// its results brought back to the host: what the grid and pair-mask tests
// compare against brute force. Test support, not part of the library.
#pragma once

#include <cstdint>
#include <vector>

#include "core/device.h"
#include "core/vec.h"
#include "nsearch/grid.h"

namespace sphray {

// The neighbour grid alone over arbitrary points: sorted order, coarse
// keys, coarse and slab offsets.
struct GridBuild {
  std::vector<uint32_t> order;  // order[k] = input index of the k-th sorted point
  std::vector<uint32_t> keys;   // sorted keys
  std::vector<uint32_t> offsets;       // coarse cells, num_cells() + 1
  std::vector<uint32_t> fine_offsets;  // x slabs (grid.h), num_fine_cells() + 1: for for_each_candidate
};
GridBuild build_grid(Backend b, const GridGeom& g, const std::vector<Vec3f>& points);

// The pair masks of the points against themselves (nsearch/pair_masks.h),
// built on the backend with `capacity` words per point, then walked on the
// host: for each sorted point (grid.order), the sorted indices its pair loop
// would visit, in their order. For tests of the GPU build.
struct PairMaskBuild {
  GridBuild grid;
  std::vector<std::vector<uint32_t>> neighbours;  // per sorted point inside the grid
  uint32_t overflowed = 0;                        // points whose masks overflowed (the direct loop serves them)
};
// With `queries`: the masks of each query (in the given order) against the
// points instead, with the points' near-cell flags (CellsNear), as the solver
// builds the fluid's wall masks; neighbours[k] belongs to queries[k].
// tensor_tiles = false: the GPU build's FMA tile test everywhere (the solver
// uses the tensor-core test where it can, nsearch/tile_mma.h).
PairMaskBuild build_pair_masks(Backend b, const GridGeom& g, const std::vector<Vec3f>& points, float radius,
                               uint32_t capacity, const std::vector<Vec3f>* queries = nullptr,
                               bool tensor_tiles = true);

// The backend's three-way split of the indices [0, n) by their classes
// (partition_three: how the incompressible solvers list the particles of
// their passes, sph/flow_solver.inl), brought back to the host.
struct PartitionBuild {
  std::vector<uint32_t> first, second, rest;  // the indices of class 0, 1 and 2
};
PartitionBuild partition_three(Backend b, const std::vector<uint8_t>& classes);

}  // namespace sphray
