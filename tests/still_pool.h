// The still pool of the render tests: 3 cm of liquid on the floor of a
// 0.4 x 0.2 m tank, six layers of particles on their 5 mm lattice, rendered
// at 192 x 108 from the default camera.
#pragma once

#include <vector>

#include "host_particles.h"
#include "field/field.h"
#include "io/scene.h"
#include "pipeline/setup.h"

namespace sphray::test {

struct StillPool {
  static constexpr double dx = 0.005;
  Scene scene = parse_scene(R"({"tank": {"min": [0,0,0], "max": [0.4,0.2,0.2]},
    "fluid": [{"min": [0,0,0], "max": [0.4,0.2,0.03]}], "sph": {"spacing": 0.005}, "run": {"end_time": 1},
    "render": {"width": 192, "height": 108}})",
                            "pool.json");
  FieldSetup fs = make_field_setup(resolve_scene(scene));
  HostParticleSet particles{measure_scene(scene).grid, lattice()};

  static std::vector<Vec3f> lattice() {
    std::vector<Vec3f> pts;
    for (int k = 0; k < 6; ++k)
      for (int j = 0; j < 40; ++j)
        for (int i = 0; i < 80; ++i)
          pts.push_back(Vec3f{float((i + 0.5) * dx), float((j + 0.5) * dx), float((k + 0.5) * dx)});
    return pts;
  }
};

}  // namespace sphray::test
