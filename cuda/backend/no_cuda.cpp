// Linked instead of solver_cuda.cu in a build without nvcc: the CUDA backend
// reports itself absent, and asking for it is a clear error.
#include <stdexcept>

#include "../../src/field.h"
#include "../../src/render.h"
#include "../../src/solver.h"

namespace sphray {

namespace {
[[noreturn]] void no_cuda() {
  throw std::runtime_error("this sphray was built without CUDA (nvcc was not found at configure time); use --backend cpu");
}
}  // namespace

bool cuda_available() { return false; }
std::string cuda_device_name() { return {}; }
size_t cuda_free_memory() { return 0; }
std::unique_ptr<Solver> make_cuda_solver(const SolverInput&) { no_cuda(); }
GridBuild build_grid_cuda(const GridGeom&, const std::vector<Vec3f>&) { no_cuda(); }
PairMaskBuild build_pair_masks_cuda(const GridGeom&, const std::vector<Vec3f>&, float, uint32_t,
                                    const std::vector<Vec3f>*, bool) {
  no_cuda();
}
std::unique_ptr<FieldBuilder> make_cuda_field_builder(const FieldSetup&) { no_cuda(); }
std::unique_ptr<Renderer> make_cuda_renderer() { no_cuda(); }

}  // namespace sphray
