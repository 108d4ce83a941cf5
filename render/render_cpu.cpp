// CPU build of the renderer: the shared implementation on the OpenMP backend.
#include "core/launch_cpu.h"
#include "render.h"
#include "screen_space.h"

#include <cmath>
#include <stdexcept>
#include <utility>
#include <vector>

#define SPHRAY_BK cpu_backend
namespace sphray::cpu_backend {
#include "render_impl.inl"
}  // namespace sphray::cpu_backend

namespace sphray {

std::unique_ptr<Renderer> make_cpu_renderer() { return std::make_unique<cpu_backend::RendererImpl>(); }

}  // namespace sphray
