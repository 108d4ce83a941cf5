// Rendering as the host sees it: the camera and environment of a tank, and
// one renderer interface over both backends (raycast.h, render_impl.inl).
// docs/rendering.md describes the method and its error against run time.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
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

class Renderer {
 public:
  virtual ~Renderer() = default;
  virtual Backend backend() const = 0;
  // Renders `field` (the backend's memory, layout and iso of `fs`) into the
  // renderer's image; with settings.skip_empty, after classifying the
  // field's bricks for the march to skip (raycast.h, Occupancy).
  virtual void render(const float* field, const FieldSetup& fs, const Camera& cam, const Environment& env,
                      const RenderSettings& rs) = 0;
  virtual double last_ms() const = 0;               // device time of the last render (occupancy included)
  virtual const uint32_t* pixels() const = 0;       // the image in the backend's memory
  virtual Image download() const = 0;
  // The viewer's interop target: the next renders write here instead (device
  // memory on CUDA, host memory on CPU), width x height pixels; null: own buffer.
  virtual void set_target(uint32_t* pixels) = 0;
};

std::unique_ptr<Renderer> make_cpu_renderer();
std::unique_ptr<Renderer> make_cuda_renderer();  // throws if CUDA is unavailable
std::unique_ptr<Renderer> make_renderer(Backend b);

// The tracer's settings in voxel units for a volume (iso from the field shape).
TraceSettings make_trace_settings(const RenderSettings& r, const FieldSetup& fs);

}  // namespace sphray
