// Which solver a scene runs (sph.solver): weakly compressible SPH (the
// solver of solver_impl.inl) or position-based fluids (pbf.h).
#pragma once

namespace sphray {

enum class SolverKind { Wcsph, Pbf };
const char* solver_name(SolverKind k);  // "wcsph", "pbf"

}  // namespace sphray
