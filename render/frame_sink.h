// The PNG sink of `run --frames-dir` and `render`: renders a solver's current
// particles (screen_space) or the field built from them (raycast, slices)
// and writes the image.
#pragma once

#include <memory>
#include <string>

#include "core/background.h"
#include "render.h"

namespace sphray {

class FrameRenderer {
 public:
  // `dir` (may be empty when only render_to is used) is created; a directory
  // that cannot be written is an error here, before any simulation, naming
  // the option that gave it (`flag`).
  // `spacing`: the particle spacing [m] (the screen-space spheres' unit).
  FrameRenderer(const RenderSettings& rs, const Box& tank, double spacing, Backend b, const FieldSetup& fs,
                const std::string& dir, const std::string& flag = "--frames-dir");
  ~FrameRenderer();  // writes what is queued; a failure is reported by finish()
  // Renders dir/frame_NNNNNN.png; the PNG is encoded and written on a
  // background thread (BackgroundQueue), so the run does not wait for it.
  // Throws std::runtime_error if an earlier write failed.
  // `field` may be null where the method needs none (method_needs_field).
  // `time`: the state's time [s] (the pose of moving obstacles).
  void write_frame(const ParticleView& particles, const FieldBuilder* field, int frame, double time = 0);
  void render_to(const ParticleView& particles, const FieldBuilder* field, const std::string& png_path,
                 double time = 0);  // at once
  // Waits for the queued PNGs; throws std::runtime_error naming a failed write.
  void finish();
  int frames_written() const { return written_ + int(png_ ? png_->done() : 0); }
  double mean_render_ms() const { return renders_ ? render_ms_ / renders_ : 0.0; }
  const std::string& dir() const { return dir_; }
  // The scene's obstacles, drawn in the frames that follow (Renderer::set_obstacles).
  void set_obstacles(const std::vector<MeshInput>& meshes) { renderer_->set_obstacles(meshes); }
  Renderer& renderer() { return *renderer_; }

 private:
  Image render(const ParticleView& particles, const FieldBuilder* field, double time);  // the image, its time counted

  std::unique_ptr<Renderer> renderer_;
  RenderSettings rs_;
  FieldSetup fs_;
  double spacing_;
  Camera cam_;
  Environment env_;
  std::string dir_, flag_;  // flag_: the option that named dir_, for messages
  int written_ = 0, renders_ = 0;
  double render_ms_ = 0;
  std::unique_ptr<BackgroundQueue> png_;  // with a directory: the PNG writer
};

}  // namespace sphray
