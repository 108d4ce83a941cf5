// What a render asks for: the scene's "render" section (docs/scenes.md),
// with its defaults in one place. Kept apart from render.h so that the scene
// does not pull in the renderer.
#pragma once

#include <string>

#include "core/config_reader.h"
#include "core/vec.h"

namespace sphray {

// How the liquid is drawn (docs/rendering.md compares them): the raycaster
// through the density field; screen-space two-sided refraction from the
// particles' spheres (Imai et al.); the density field sampled on
// view-aligned slices (Mishima et al.).
enum class RenderMethod { Raycast, ScreenSpace, Slices };
const char* render_method_name(RenderMethod m);
RenderMethod parse_render_method(const std::string& name);  // throws std::invalid_argument listing the valid ones
// The screen-space method draws the particles, the others the field.
inline bool method_needs_field(RenderMethod m) { return m != RenderMethod::ScreenSpace; }

struct RenderSettings {
  RenderMethod method = RenderMethod::Raycast;
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
  // screen_space: sphere radius [particle spacings]; the bilateral filter's
  // half-width w [pixels] and passes over both depth maps
  double sphere_radius = 1.5;
  int filter_width = 4;
  int filter_iterations = 4;
  int slices = 256;         // slices: view-aligned planes across the volume's depth
  // Camera [m]; eye == target means "auto" (a three-quarter view of the tank).
  Vec3d eye{0, 0, 0}, target{0, 0, 0};
  double fov = 40;          // vertical, degrees
  int frames_every = 1;     // --frames-dir: a PNG every K-th output frame
};

RenderSettings read_render_settings(const ConfigReader& r);

}  // namespace sphray
