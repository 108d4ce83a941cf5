// CUDA-OpenGL interop for the viewer: a GL pixel buffer that the CUDA
// raycaster writes into directly (cudaGraphicsGLRegisterBuffer). Compiled
// only with the CUDA backend; the CPU path uploads a host image instead.
#pragma once

#include <cstdint>

namespace sphray {

class GlPixelBufferCuda {
 public:
  explicit GlPixelBufferCuda(unsigned gl_buffer);  // registers it (write-discard)
  ~GlPixelBufferCuda();
  GlPixelBufferCuda(const GlPixelBufferCuda&) = delete;
  GlPixelBufferCuda& operator=(const GlPixelBufferCuda&) = delete;
  uint32_t* map();  // device pointer, valid until unmap()
  void unmap();

 private:
  void* resource_ = nullptr;
};

}  // namespace sphray
