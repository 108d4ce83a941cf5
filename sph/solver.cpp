#include "solver.h"

#include "skin.h"

namespace sphray {

const char* solver_name(SolverKind k) {
  switch (k) {
    case SolverKind::Pbf: return "pbf";
    case SolverKind::Dfsph: return "dfsph";
    default: return "wcsph";
  }
}

#if !defined(SPHRAY_HAVE_CUDA)
std::unique_ptr<Solver> make_cuda_solver(const SolverInput&) { throw_no_cuda(); }
std::unique_ptr<SkinSet> make_cuda_skin_set(std::vector<SkinGeometry>, const SphParams&) { throw_no_cuda(); }
#endif

}  // namespace sphray
