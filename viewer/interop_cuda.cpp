#include "interop.h"

#include <stdexcept>
#include <string>

#include <GL/glew.h>
#include <cuda_gl_interop.h>
#include <cuda_runtime.h>

namespace sphray {

namespace {
void check(cudaError_t e, const char* what) {
  if (e != cudaSuccess) throw std::runtime_error(std::string("CUDA-OpenGL interop: ") + what + ": " + cudaGetErrorString(e));
}
}  // namespace

GlPixelBufferCuda::GlPixelBufferCuda(unsigned gl_buffer) {
  cudaGraphicsResource_t r = nullptr;
  check(cudaGraphicsGLRegisterBuffer(&r, gl_buffer, cudaGraphicsRegisterFlagsWriteDiscard), "register buffer");
  resource_ = r;
}

GlPixelBufferCuda::~GlPixelBufferCuda() {
  if (resource_) cudaGraphicsUnregisterResource(static_cast<cudaGraphicsResource_t>(resource_));
}

uint32_t* GlPixelBufferCuda::map() {
  auto r = static_cast<cudaGraphicsResource_t>(resource_);
  check(cudaGraphicsMapResources(1, &r), "map");
  void* p = nullptr;
  size_t bytes = 0;
  check(cudaGraphicsResourceGetMappedPointer(&p, &bytes, r), "mapped pointer");
  return static_cast<uint32_t*>(p);
}

void GlPixelBufferCuda::unmap() {
  auto r = static_cast<cudaGraphicsResource_t>(resource_);
  check(cudaGraphicsUnmapResources(1, &r), "unmap");
}

}  // namespace sphray
