// The viewer's scene, in every build (with or without the viewer): a run
// over several ranks resolves it on every rank (apps/cmd_view.cpp). The
// built-in scene runs PBF, whose steps play it about six times faster than
// WCSPH's acoustic steps on two CPU cores (docs/rendering.md, "The viewer").
#include "io/scene.h"
#include "viewer.h"

namespace sphray {

const char* small_view_scene() {
  return R"({"name": "small_dam_break",
  "description": "The dam break at 4 cm spacing (1,120 particles) under position-based fluids: interactive on the CPU backend.",
  "tank": {"min": [0, 0, 0], "max": [1.6, 0.67, 0.6]},
  "fluid": [{"min": [0, 0, 0], "max": [0.4, 0.67, 0.3]}],
  "sph": {"spacing": 0.04, "solver": "pbf"},
  "render": {"width": 640, "height": 360},
  "run": {"end_time": 3.0, "output_interval": 0.02}})";
}

ResolvedScene resolve_view_scene(const ViewOptions& opt) {
  return resolve_scene(opt.scene.empty() ? parse_scene(small_view_scene(), "(built-in small dam break)", opt.sets)
                                         : load_scene(opt.scene, opt.sets));
}

}  // namespace sphray
