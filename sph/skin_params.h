// What a scene says about an obstacle's skin (sph/skin.h runs its waves).
#pragma once

#include <cstdint>

#include "mesh/mesh.h"
#include "obstacles.h"

namespace sphray {

// The Laplacian on the texels: weights fitted per texel to its eight
// neighbours' positions in its tangent plane (least squares: exact for
// quadratics on the skewed grid near the cube's corners, the default);
// Kira et al.'s fixed weights over the neighbours' distances on the surface;
// or the same at the mean texel spacing (texture space, uncorrected).
// docs/validation.md compares their wave speeds by direction.
enum class SkinStencil { Fitted, Surface, Texture };

struct SkinParams {
  int resolution = 48;       // texels along a cube edge (6 n^2 in all)
  float wave_speed = 1.0f;   // s [m/s]
  float damping = 3.0f;      // zeta [1/s]
  float frequency = 4.0f;    // f0 [Hz] of the restoring foundation
  float compliance = 1e-6f;  // steady dent per pascal [m/Pa]
  SkinStencil stencil = SkinStencil::Fitted;
};

// One skinned obstacle as the solver's input gives it.
struct SkinInput {
  uint32_t obstacle = 0;  // its index in SolverInput::obstacles
  TriangleMesh mesh;      // placed (the pose at t = 0), world coordinates
  Motion motion{};
  SkinParams params{};
};

}  // namespace sphray
