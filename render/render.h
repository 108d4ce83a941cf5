// Rendering as the host sees it: the camera and environment of a tank, and
// one renderer interface over both backends (raycast.h, render_impl.inl).
// docs/rendering.md describes the method and its error against run time.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "image.h"
#include "raycast.h"
#include "field/field.h"
#include "render_settings.h"
#include "sph/solver.h"

namespace sphray {

// A pinhole camera at eye looking at target, z up; vertical field of view in degrees.
Camera look_at(Vec3d eye, Vec3d target, double fov_deg, int width, int height);
// The camera's eye and target: render.eye/target, or (unset) the automatic
// three-quarter view of the tank.
void camera_points(const Box& tank, const RenderSettings& r, Vec3d& eye, Vec3d& target);
// The camera (render.eye/target/fov, or the automatic view) at the render's size.
Camera make_camera(const Box& tank, const RenderSettings& r);
// The tank, floor and sky in the voxel units of `vol`; the walls that face
// the camera are clear glass, the others tiled.
Environment make_environment(const Box& tank, const VolumeGeom& vol, const Camera& cam);

// What a renderer draws from, in its backend's memory: the density field
// (raycast, slices) or the particles (screen_space). The field's setup is
// always given: its volume is the environment's frame.
struct RenderInput {
  const float* field = nullptr;       // null: not built (screen_space needs none)
  const FieldSetup* setup = nullptr;  // the volume's layout and iso
  ParticleView particles{};           // screen_space: the fluid particles
  double spacing = 0;                 // screen_space: the particle spacing [m] (sphere radius unit)
  double time = 0;                    // [s] the state's time: the pose of moving obstacles
};

class Renderer {
 public:
  virtual ~Renderer() = default;
  virtual Backend backend() const = 0;
  // Renders by settings.method into the renderer's image. raycast and
  // slices: with settings.skip_empty, after classifying the field's bricks
  // for the march to skip (raycast.h, Occupancy); screen_space: the three
  // passes of screen_space.h. A method without its input is a logic_error.
  virtual void render(const RenderInput& in, const Camera& cam, const Environment& env, const RenderSettings& rs) = 0;
  // A field alone (raycast, slices).
  void render(const float* field, const FieldSetup& fs, const Camera& cam, const Environment& env,
              const RenderSettings& rs) {
    render(RenderInput{field, &fs, {}, 0}, cam, env, rs);
  }
  virtual double last_ms() const = 0;               // device time of the last render (occupancy included)
  // The last render's stages and their device ms (screen_space: depth,
  // filter, shade; the others: occupancy, trace).
  virtual std::vector<std::pair<std::string, double>> last_stages() const = 0;
  virtual const uint32_t* pixels() const = 0;       // the image in the backend's memory
  virtual Image download() const = 0;
  // The scene's obstacles (world coordinates), kept for the renders that
  // follow: raycast and slices draw them (raycast.h, MeshHits); screen_space
  // does not. Their BVHs are built here, once, on the renderer's backend.
  virtual void set_obstacles(const std::vector<MeshInput>& meshes) = 0;
  // New vertex positions (same count and triangles) for obstacle k, its
  // BVH refitted: a skin's displaced surface (sph/skin.h).
  virtual void set_obstacle_vertices(uint32_t k, const std::vector<Vec3f>& vertices) = 0;
  // The viewer's interop target: the next renders write here instead (device
  // memory on CUDA, host memory on CPU), width x height pixels; null: own buffer.
  virtual void set_target(uint32_t* pixels) = 0;
};

std::unique_ptr<Renderer> make_cpu_renderer();
std::unique_ptr<Renderer> make_cuda_renderer();  // throws if CUDA is unavailable
std::unique_ptr<Renderer> make_renderer(Backend b);

// The tracer's settings in voxel units for a volume (iso from the field
// shape); with the slices method, the camera's planes across the volume.
TraceSettings make_trace_settings(const RenderSettings& r, const FieldSetup& fs, const Camera& cam);

}  // namespace sphray
