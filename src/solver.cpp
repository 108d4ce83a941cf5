#include "solver.h"

namespace sphray {

GridBuild build_grid_cpu(const GridGeom& g, const std::vector<Vec3f>& points);
GridBuild build_grid_cuda(const GridGeom& g, const std::vector<Vec3f>& points);

const char* backend_name(Backend b) { return b == Backend::Cuda ? "cuda" : "cpu"; }

GridBuild build_grid(Backend b, const GridGeom& g, const std::vector<Vec3f>& points) {
  return b == Backend::Cuda ? build_grid_cuda(g, points) : build_grid_cpu(g, points);
}

}  // namespace sphray
