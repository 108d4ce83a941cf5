#include "solver.h"

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
#endif

}  // namespace sphray
