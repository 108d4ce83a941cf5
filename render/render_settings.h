// What a render asks for: the scene's "render" section (docs/scenes.md),
// with its defaults in one place. Kept apart from render.h so that the scene
// does not pull in the renderer.
#pragma once

#include "core/config_reader.h"
#include "core/vec.h"

namespace sphray {

struct RenderSettings {
  int width = 640, height = 360;
  int interfaces = 4;       // interfaces followed per ray, 1 .. 8
  float step = 0.5f;        // march step [voxels], (0, 0.5]
  int secant_steps = 3;     // after the linear interpolation of a hit
  float ior = 1.33f;        // refractive index of the liquid
  Vec3d absorption{8, 2, 1};  // Beer-Lambert [1/m], r g b
  Vec3d tint{0.02, 0.13, 0.18};  // colour the absorbed share turns into (deep liquid's colour), linear r g b
  bool reflections = true;  // trace the reflected branch too (else it takes the environment)
  int budget = 8;           // interfaces per pixel for the branches after the first path, 1 .. 64
  double min_weight = 1.0 / 256;  // weaker branches take the environment, [0, 1]
  bool skip_empty = true;   // the march jumps over bricks the surface cannot cross
  // Camera [m]; eye == target means "auto" (a three-quarter view of the tank).
  Vec3d eye{0, 0, 0}, target{0, 0, 0};
  double fov = 40;          // vertical, degrees
  int frames_every = 1;     // --frames-dir: a PNG every K-th output frame
};

RenderSettings read_render_settings(const ConfigReader& r);

}  // namespace sphray
