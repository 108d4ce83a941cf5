// What a scene says about an obstacle's skin (sph/skin.h runs its waves).
#pragma once

#include <cstdint>

#include "mesh/mesh.h"
#include "mesh/skin_map.h"
#include "obstacles.h"

namespace sphray {

// The Laplacian on the texels: Kira et al.'s eight neighbours at their
// distances on the surface, edge neighbours 2/3 and diagonals 1/3 (the
// default); weights fitted per texel to the neighbours' positions in its
// tangent plane (least squares: exact for quadratics on the skewed grid
// near the cube's corners, so more isotropic on round meshes, but not
// symmetric: on a mesh whose map squeezes texels, as the bunny's, free
// waves grow; a texel whose fit has a negative weight keeps the paper's);
// or the paper's weights at the mean texel spacing (texture space,
// uncorrected). docs/validation.md compares their speeds by direction.
enum class SkinStencil { Surface, Fitted, Texture };

struct SkinParams {
  int resolution = 48;       // texels along a cube edge (6 n^2 in all)
  float wave_speed = 1.0f;   // s [m/s]
  float damping = 3.0f;      // zeta [1/s]
  float frequency = 4.0f;    // f0 [Hz] of the restoring foundation
  float compliance = 1e-6f;  // steady dent per pascal [m/Pa]
  SkinStencil stencil = SkinStencil::Surface;
};

// One skinned obstacle as the solver's input gives it.
struct SkinInput {
  uint32_t obstacle = 0;  // its index in SolverInput::obstacles
  TriangleMesh mesh;      // placed (the pose at t = 0), world coordinates
  Motion motion{};
  SkinParams params{};
  SphereEmbedding embedding;  // the mesh's embed_on_sphere, as the scene checked it (empty: computed again)
};

}  // namespace sphray
