#include "solver.h"

namespace sphray {

const char* solver_name(SolverKind k) { return k == SolverKind::Pbf ? "pbf" : "wcsph"; }

#if !defined(SPHRAY_HAVE_CUDA)
std::unique_ptr<Solver> make_cuda_solver(const SolverInput&) { throw_no_cuda(); }
#endif

}  // namespace sphray
