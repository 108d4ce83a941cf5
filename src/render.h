// Rendering as the host sees it: settings from the scene's "render" section,
// the camera, one renderer interface over both backends (cuda/render/), and
// images (PNG via stb, PSNR). docs/rendering.md describes the method and its
// error against run time.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "../cuda/render/raycast.h"
#include "field.h"
#include "background.h"
#include "render_settings.h"
#include "solver.h"

namespace sphray {

struct Scene;

// A pinhole camera at eye looking at target, z up; vertical field of view in degrees.
Camera look_at(Vec3d eye, Vec3d target, double fov_deg, int width, int height);
// The camera's eye and target: render.eye/target, or (unset) the automatic
// three-quarter view of the scene's tank.
void camera_points(const Scene& s, const RenderSettings& r, Vec3d& eye, Vec3d& target);
// The scene's camera (render.eye/target/fov, or the automatic view) at the render's size.
Camera make_camera(const Scene& s, const RenderSettings& r);
// The tank, floor and sky in the voxel units of `vol`; the walls that face
// the camera are clear glass, the others tiled.
Environment make_environment(const Scene& s, const VolumeGeom& vol, const Camera& cam);

struct Image {
  int width = 0, height = 0;
  std::vector<uint32_t> rgba;  // row 0 at the top, R in the low byte
};

class Renderer {
 public:
  virtual ~Renderer() = default;
  virtual Backend backend() const = 0;
  // Renders `field` (the backend's memory, layout and iso of `fs`) into the
  // renderer's image. `particles` gives the SPH cell occupancy for the
  // empty-space skip (null, or settings.skip_empty false: no skip).
  virtual void render(const float* field, const FieldSetup& fs, const ParticleView* particles, const Camera& cam,
                      const Environment& env, const RenderSettings& rs) = 0;
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

// The PNG sink of `run --frames-dir` and `render`: renders a solver's current
// particles from the field built for them and writes the image.
class FrameRenderer {
 public:
  // `dir` (may be empty when only render_to is used) is created; a directory
  // that cannot be written is an error here, before any simulation, naming
  // the option that gave it (`flag`).
  FrameRenderer(const Scene& s, Backend b, const FieldSetup& fs, const std::string& dir,
                const std::string& flag = "--frames-dir");
  ~FrameRenderer();  // writes what is queued; a failure is reported by finish()
  // Renders dir/frame_NNNNNN.png; the PNG is encoded and written on a
  // background thread (BackgroundQueue), so the run does not wait for it.
  // Throws std::runtime_error if an earlier write failed.
  void write_frame(const ParticleView& pv, const FieldBuilder& field, int frame);
  void render_to(const ParticleView& pv, const FieldBuilder& field, const std::string& png_path);  // written at once
  // Waits for the queued PNGs; throws std::runtime_error naming a failed write.
  void finish();
  int frames_written() const { return written_ + int(png_ ? png_->done() : 0); }
  double mean_render_ms() const { return renders_ ? render_ms_ / renders_ : 0.0; }
  const std::string& dir() const { return dir_; }

 private:
  Image render(const ParticleView& pv, const FieldBuilder& field);  // the image, its time counted

  std::unique_ptr<Renderer> renderer_;
  RenderSettings rs_;
  Camera cam_;
  Environment env_;
  std::string dir_, flag_;  // flag_: the option that named dir_, for messages
  int written_ = 0, renders_ = 0;
  double render_ms_ = 0;
  std::unique_ptr<BackgroundQueue> png_;  // with a directory: the PNG writer
};

// PNG through stb_image_write; throws std::runtime_error naming the path.
void write_png(const std::string& path, const Image& img);
Image read_png(const std::string& path);
// Pixels where some channel of R, G, B differs by more than `levels`.
size_t pixels_differing(const Image& a, const Image& b, int levels);
// Peak signal-to-noise ratio over R, G, B (8-bit), in dB; +inf for equal images.
double psnr(const Image& a, const Image& b);

}  // namespace sphray
