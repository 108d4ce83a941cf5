// Which solver a scene runs (sph.solver): weakly compressible SPH (the
// solver of solver_impl.inl), position-based fluids (pbf.h) or
// divergence-free SPH (dfsph.h).
#pragma once

namespace sphray {

enum class SolverKind { Wcsph, Pbf, Dfsph };
const char* solver_name(SolverKind k);  // "wcsph", "pbf", "dfsph"

// The incompressible solvers: steps on the flow speed, walls as the tank's planes.
inline bool incompressible(SolverKind k) { return k != SolverKind::Wcsph; }

}  // namespace sphray
