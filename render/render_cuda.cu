// CUDA build of the renderer: the shared implementation on the CUDA backend.
#include "core/launch_cuda.cuh"
#include "render.h"
#include "screen_space.h"

#include <cmath>
#include <stdexcept>
#include <utility>
#include <vector>

#define SPHRAY_BK cuda_backend
namespace sphray::cuda_backend {
#include "render_impl.inl"
}  // namespace sphray::cuda_backend

namespace sphray {

std::unique_ptr<Renderer> make_cuda_renderer() {
  if (!cuda_available()) throw std::runtime_error("the CUDA backend was asked for, but no CUDA device is present");
  return std::make_unique<cuda_backend::RendererImpl>();
}

}  // namespace sphray
