#include "render.h"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <stdexcept>

#include <stb_image.h>
#include <stb_image_write.h>

#include "scene.h"

namespace sphray {

namespace {

Vec3f to_f(Vec3d v) { return {float(v.x), float(v.y), float(v.z)}; }

// PNG rows without a prediction filter. stb's default tries all five filters
// per row and keeps the best by its heuristic: on these images that took 3.5x
// as long (423 vs 123 ms for a 1920x1080 frame on the 2-core machine) and made
// larger files (347 vs 336 kB). Set once, before any writer thread exists.
const bool png_filter_none = (stbi_write_force_png_filter = 0, true);

}  // namespace

Camera look_at(Vec3d eye, Vec3d target, double fov_deg, int width, int height) {
  Camera c{};
  const Vec3d f = (target - eye) * (1.0 / length(target - eye));
  Vec3d right{f.y, -f.x, 0.0};  // f x (0, 0, 1)
  if (length(right) < 1e-9) right = {1, 0, 0};  // looking straight up or down
  right = right * (1.0 / length(right));
  const Vec3d up{right.y * f.z - right.z * f.y, right.z * f.x - right.x * f.z, right.x * f.y - right.y * f.x};
  c.eye = to_f(eye);
  c.forward = to_f(f);
  c.right = to_f(right);
  c.up = to_f(up);
  c.tan_half_fov = float(std::tan(fov_deg * M_PI / 360.0));
  c.width = width;
  c.height = height;
  return c;
}

void camera_points(const Scene& s, const RenderSettings& r, Vec3d& eye, Vec3d& target) {
  eye = r.eye;
  target = r.target;
  if (length(eye - target) > 0) return;
  // Three-quarter view from the front (-y), a little to the right and above,
  // far enough that the whole tank fits the field of view.
  const Vec3d lo = s.tank.min, hi = s.tank.max, size = hi - lo;
  target = {lo.x + 0.5 * size.x, lo.y + 0.5 * size.y, lo.z + 0.3 * size.z};
  Vec3d dir{0.3, -1.0, 0.55};
  dir = dir * (1.0 / length(dir));
  const double tan_half = std::tan(r.fov * M_PI / 360.0), aspect = double(r.width) / double(r.height);
  eye = target + dir * (0.5 * length(size) / std::min(tan_half, tan_half * aspect) * 0.95);
}

Camera make_camera(const Scene& s, const RenderSettings& r) {
  Vec3d eye, target;
  camera_points(s, r, eye, target);
  return look_at(eye, target, r.fov, r.width, r.height);
}

Environment make_environment(const Scene& s, const VolumeGeom& vol, const Camera& cam) {
  const Vec3d size = s.tank.max - s.tank.min;
  Environment e{};
  e.tank_lo = vol.to_voxels(to_f(s.tank.min));
  e.tank_hi = vol.to_voxels(to_f(s.tank.max));
  e.tile = float(std::max(size.x, size.y) / 16.0 / vol.voxel);
  e.sun = normalized(Vec3f{0.45f, 0.25f, 0.86f});
  // a wall is glass when the camera is on its outer side
  e.glass = (cam.eye.x < s.tank.min.x ? 1 : 0) | (cam.eye.x > s.tank.max.x ? 2 : 0) |
            (cam.eye.y < s.tank.min.y ? 4 : 0) | (cam.eye.y > s.tank.max.y ? 8 : 0);
  return e;
}

TraceSettings make_trace_settings(const RenderSettings& r, const FieldSetup& fs) {
  const double v = fs.geom.voxel;
  return TraceSettings{fs.shape.iso,
                       r.step,
                       r.interfaces,
                       r.ior,
                       Rgb{float(r.absorption.x * v), float(r.absorption.y * v), float(r.absorption.z * v)},
                       r.secant_steps};
}

std::unique_ptr<Renderer> make_renderer(Backend b) {
  return b == Backend::Cuda ? make_cuda_renderer() : make_cpu_renderer();
}

FrameRenderer::FrameRenderer(const Scene& s, Backend b, const FieldSetup& fs, const std::string& dir,
                             const std::string& flag)
    : renderer_(make_renderer(b)), rs_(s.render), cam_(make_camera(s, s.render)),
      dir_(dir), flag_(flag) {
  env_ = make_environment(s, fs.geom, cam_);
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

Image FrameRenderer::render(const ParticleView& pv, const FieldBuilder& field) {
  renderer_->render(field.data(), field.setup(), &pv, cam_, env_, rs_);
  render_ms_ += renderer_->last_ms();
  ++renders_;
  return renderer_->download();
}

void FrameRenderer::render_to(const ParticleView& pv, const FieldBuilder& field, const std::string& png_path) {
  try {
    write_png(png_path, render(pv, field));
  } catch (const std::runtime_error& e) {  // after the run that made the image
    throw OutputError(e.what());
  }
  ++written_;
}

void FrameRenderer::write_frame(const ParticleView& pv, const FieldBuilder& field, int frame) {
  if (!png_) throw std::logic_error("FrameRenderer::write_frame needs a directory");
  char name[32];
  std::snprintf(name, sizeof name, "frame_%06d.png", frame);
  // The image leaves the renderer now (the next render reuses its buffer); stb encodes it on the writer thread.
  auto img = std::make_shared<Image>(render(pv, field));
  const std::string path = (std::filesystem::path(dir_) / name).string();
  if (!png_->submit([img, path] { write_png(path, *img); })) throw OutputError(flag_ + ": " + png_->error());
}

// stb's stbi_write_png ignores the errors of fwrite and fclose: on a full disk
// it left empty and truncated frames and reported success. So stb encodes to
// memory, and the bytes go to path.tmp with every error checked and are then
// renamed over path: a frame_NNNNNN.png is always whole (a failed or killed
// write leaves at most a .tmp).
void write_png(const std::string& path, const Image& img) {
  if (img.width <= 0 || img.height <= 0 || img.rgba.size() != size_t(img.width) * size_t(img.height))
    throw std::runtime_error("write_png: '" + path + "': image has no pixels or the wrong size");
  std::vector<unsigned char> png;
  auto append = [](void* out, void* data, int size) {
    auto* v = static_cast<std::vector<unsigned char>*>(out);
    v->insert(v->end(), static_cast<unsigned char*>(data), static_cast<unsigned char*>(data) + size);
  };
  if (!stbi_write_png_to_func(append, &png, img.width, img.height, 4, img.rgba.data(), img.width * 4))
    throw std::runtime_error("cannot encode PNG '" + path + "'");
  const std::string tmp = path + ".tmp";
  auto fail = [&](int err) {
    std::remove(tmp.c_str());
    throw std::runtime_error("cannot write PNG '" + path + "': " + std::strerror(err));
  };
  errno = 0;
  std::FILE* f = std::fopen(tmp.c_str(), "wb");
  if (!f) fail(errno);
  const bool written = std::fwrite(png.data(), 1, png.size(), f) == png.size();
  const int write_err = errno;
  if (std::fclose(f) != 0 || !written) fail(written ? errno : write_err);
  if (std::rename(tmp.c_str(), path.c_str()) != 0) fail(errno);
}

Image read_png(const std::string& path) {
  int w = 0, h = 0, ch = 0;
  unsigned char* data = stbi_load(path.c_str(), &w, &h, &ch, 4);
  if (!data) throw std::runtime_error("cannot read PNG '" + path + "': " + stbi_failure_reason());
  Image img;
  img.width = w;
  img.height = h;
  img.rgba.resize(size_t(w) * size_t(h));
  std::memcpy(img.rgba.data(), data, img.rgba.size() * 4);
  stbi_image_free(data);
  return img;
}

namespace {
void check_same_size(const Image& a, const Image& b, const char* what) {
  if (a.width != b.width || a.height != b.height || a.rgba.size() != b.rgba.size() || a.rgba.empty())
    throw std::invalid_argument(std::string(what) + ": images differ in size");
}
int channel(uint32_t px, int c) { return int((px >> (8 * c)) & 0xff); }
}  // namespace

size_t pixels_differing(const Image& a, const Image& b, int levels) {
  check_same_size(a, b, "pixels_differing");
  size_t n = 0;
  for (size_t i = 0; i < a.rgba.size(); ++i)
    for (int c = 0; c < 3; ++c)
      if (std::abs(channel(a.rgba[i], c) - channel(b.rgba[i], c)) > levels) {
        ++n;
        break;
      }
  return n;
}

double psnr(const Image& a, const Image& b) {
  check_same_size(a, b, "psnr");
  double se = 0;
  for (size_t i = 0; i < a.rgba.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      const double d = double(channel(a.rgba[i], c) - channel(b.rgba[i], c));
      se += d * d;
    }
  const double mse = se / (3.0 * double(a.rgba.size()));
  if (mse == 0) return std::numeric_limits<double>::infinity();
  return 10.0 * std::log10(255.0 * 255.0 / mse);
}

}  // namespace sphray
