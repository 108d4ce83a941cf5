#include "frame_sink.h"

#include <cstdio>
#include <filesystem>
#include <stdexcept>

namespace sphray {

FrameRenderer::FrameRenderer(const RenderSettings& rs, const Box& tank, double spacing, Backend b,
                             const FieldSetup& fs, const std::string& dir, const std::string& flag)
    : renderer_(make_renderer(b)), rs_(rs), fs_(fs), spacing_(spacing), cam_(make_camera(tank, rs)), dir_(dir),
      flag_(flag) {
  env_ = make_environment(tank, fs.geom, cam_);
  if (dir_.empty()) return;
  std::error_code ec;
  std::filesystem::create_directories(dir_, ec);
  if (ec || !std::filesystem::is_directory(dir_))
    throw std::runtime_error(flag + ": cannot create directory '" + dir_ + "'" + (ec ? ": " + ec.message() : ""));
  const std::string probe = (std::filesystem::path(dir_) / ".sphray_write_test").string();
  std::FILE* f = std::fopen(probe.c_str(), "wb");
  if (!f) throw std::runtime_error(flag + ": cannot write into '" + dir_ + "'");
  std::fclose(f);
  std::remove(probe.c_str());
  png_ = std::make_unique<BackgroundQueue>();
}

FrameRenderer::~FrameRenderer() {
  if (png_) png_->finish();  // errors are reported by an explicit finish()
}

void FrameRenderer::finish() {
  if (png_ && !png_->finish()) throw OutputError(flag_ + ": " + png_->error());
}

Image FrameRenderer::render(const ParticleView& particles, const FieldBuilder* field, double time) {
  renderer_->render(RenderInput{field ? field->data() : nullptr, &fs_, particles, spacing_, time}, cam_, env_, rs_);
  render_ms_ += renderer_->last_ms();
  ++renders_;
  return renderer_->download();
}

void FrameRenderer::render_to(const ParticleView& particles, const FieldBuilder* field, const std::string& png_path,
                              double time) {
  try {
    write_png(png_path, render(particles, field, time));
  } catch (const std::runtime_error& e) {  // after the run that made the image
    throw OutputError(e.what());
  }
  ++written_;
}

void FrameRenderer::write_frame(const ParticleView& particles, const FieldBuilder* field, int frame, double time) {
  if (!png_) throw std::logic_error("FrameRenderer::write_frame needs a directory");
  char name[32];
  std::snprintf(name, sizeof name, "frame_%06d.png", frame);
  // The image leaves the renderer now (the next render reuses its buffer); stb encodes it on the writer thread.
  auto img = std::make_shared<Image>(render(particles, field, time));
  const std::string path = (std::filesystem::path(dir_) / name).string();
  if (!png_->submit([img, path] { write_png(path, *img); })) throw OutputError(flag_ + ": " + png_->error());
}

}  // namespace sphray
