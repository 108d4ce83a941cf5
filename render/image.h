// An RGBA image on the host, PNG files through stb, and image error (PSNR, SSIM).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace sphray {

struct Image {
  int width = 0, height = 0;
  std::vector<uint32_t> rgba;  // row 0 at the top, R in the low byte
};

// PNG through stb_image_write; throws std::runtime_error naming the path.
void write_png(const std::string& path, const Image& img);
Image read_png(const std::string& path);
// Pixels where some channel of R, G, B differs by more than `levels`.
size_t pixels_differing(const Image& a, const Image& b, int levels);
// Peak signal-to-noise ratio over R, G, B (8-bit), in dB; +inf for equal images.
double psnr(const Image& a, const Image& b);
// Mean structural similarity (Wang, Bovik, Sheikh & Simoncelli 2004) of the
// luma (Rec. 601 weights, 8-bit scale): Gaussian window 11 x 11, sigma 1.5,
// K1 = 0.01, K2 = 0.03, over the windows that lie inside the image (at least
// 11 x 11 pixels). 1 for equal images.
double ssim(const Image& a, const Image& b);

}  // namespace sphray
