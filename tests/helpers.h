// Shared test helpers: small scenes in JSON text, and running a solver to a time.
#pragma once

#include <string>

#include "../src/pipeline.h"
#include "../src/scene.h"
#include "../src/setup.h"
#include "../src/solver.h"

namespace sphray::test {

inline std::string source_path(const std::string& rel) { return std::string(SPHRAY_SOURCE_DIR) + "/" + rel; }

// Within the scene's tank (walls included).
inline bool inside(const Vec3f& p, const Scene& s) {
  return p.x >= s.tank.min.x && p.y >= s.tank.min.y && p.z >= s.tank.min.z && p.x <= s.tank.max.x &&
         p.y <= s.tank.max.y && p.z <= s.tank.max.z;
}

inline void run_until(Solver& s, double t) {
  while (s.time() < t - 1e-12) s.step(t);
}

}  // namespace sphray::test
