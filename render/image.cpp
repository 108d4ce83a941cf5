#include "image.h"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <stdexcept>

#include <stb_image.h>
#include <stb_image_write.h>

namespace sphray {

namespace {

// PNG rows without a prediction filter. stb's default tries all five filters
// per row and keeps the best by its heuristic: on these images that takes
// several times as long and makes no smaller files (docs/rendering.md). Set
// once, before any writer thread exists.
const bool png_filter_none = (stbi_write_force_png_filter = 0, true);

}  // namespace

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

double ssim(const Image& a, const Image& b) {
  check_same_size(a, b, "ssim");
  const int w = a.width, h = a.height, r = 5;  // window 2r + 1
  if (w < 2 * r + 1 || h < 2 * r + 1) throw std::invalid_argument("ssim: images smaller than the 11 x 11 window");
  double g[2 * r + 1], gs = 0;
  for (int k = -r; k <= r; ++k) gs += g[k + r] = std::exp(-double(k * k) / (2.0 * 1.5 * 1.5));
  for (double& v : g) v /= gs;
  auto luma = [](uint32_t px) { return 0.299 * channel(px, 0) + 0.587 * channel(px, 1) + 0.114 * channel(px, 2); };
  // The five moments x, y, x^2, y^2, xy, filtered along rows then columns
  // (valid region only).
  const int ow = w - 2 * r, oh = h - 2 * r;
  std::vector<double> rows(size_t(5) * size_t(ow) * size_t(h));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < ow; ++x) {
      double m[5] = {0, 0, 0, 0, 0};
      for (int k = 0; k <= 2 * r; ++k) {
        const size_t q = size_t(y) * size_t(w) + size_t(x + k);
        const double u = luma(a.rgba[q]), v = luma(b.rgba[q]);
        m[0] += g[k] * u;
        m[1] += g[k] * v;
        m[2] += g[k] * u * u;
        m[3] += g[k] * v * v;
        m[4] += g[k] * u * v;
      }
      for (int c = 0; c < 5; ++c) rows[(size_t(c) * size_t(h) + size_t(y)) * size_t(ow) + size_t(x)] = m[c];
    }
  const double c1 = (0.01 * 255) * (0.01 * 255), c2 = (0.03 * 255) * (0.03 * 255);
  double sum = 0;
  for (int y = 0; y < oh; ++y)
    for (int x = 0; x < ow; ++x) {
      double m[5] = {0, 0, 0, 0, 0};
      for (int c = 0; c < 5; ++c)
        for (int k = 0; k <= 2 * r; ++k) m[c] += g[k] * rows[(size_t(c) * size_t(h) + size_t(y + k)) * size_t(ow) + size_t(x)];
      const double va = m[2] - m[0] * m[0], vb = m[3] - m[1] * m[1], cov = m[4] - m[0] * m[1];
      sum += (2 * m[0] * m[1] + c1) * (2 * cov + c2) / ((m[0] * m[0] + m[1] * m[1] + c1) * (va + vb + c2));
    }
  return sum / (double(ow) * double(oh));
}

}  // namespace sphray
