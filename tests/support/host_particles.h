// A particle set held on the host, sorted by a grid, viewed as the CPU
// backend sees a solver's particles: the input of the field and render tests.
// Test support, not part of the library.
#pragma once

#include <cstdint>
#include <vector>

#include "sph/solver.h"

namespace sphray {

// Presence optional ([6][n] in the order of `points`).
struct HostParticleSet {
  std::vector<Float4> pos;
  std::vector<uint32_t> offsets, fine_offsets;
  std::vector<float> presence;
  GridGeom grid{};
  HostParticleSet(const GridGeom& g, const std::vector<Vec3f>& points, const std::vector<float>& presence_in = {});
  ParticleView view() const;
};

}  // namespace sphray
