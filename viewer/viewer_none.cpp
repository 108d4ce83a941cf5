// Linked when GLFW, GLEW or Dear ImGui were not found at configure time.
#include <stdexcept>

#include "viewer.h"

namespace sphray {

bool viewer_built() { return false; }
int run_viewer(const ViewOptions&, std::ostream&) {
  throw std::runtime_error(
      "this sphray was built without the viewer (GLFW, GLEW or Dear ImGui were not found at configure time: "
      "install libglfw3-dev libglew-dev libimgui-dev, or use sphray run --frames-dir / sphray render)");
}

}  // namespace sphray
