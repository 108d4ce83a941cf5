// `sphray view`: the real-time dam break in a window (GLFW + GLEW + Dear
// ImGui). Each frame: the SPH steps that bring the simulation to the wall
// time of the previous frame (or a fixed number of substeps), the density
// field, the raycast; the image
// reaches the screen through CUDA-OpenGL interop on CUDA (no copy through the
// host) and by texture upload on the CPU. docs/rendering.md, "The viewer".
#pragma once

#include <functional>
#include <iosfwd>
#include <memory>
#include <string>
#include <vector>

#include "pipeline/setup.h"
#include "sph/solver.h"

namespace sphray {

// Makes the viewer's solver for the resolved scene on a backend (at start
// and on reset).
using ViewSolverMaker = std::function<std::unique_ptr<Solver>(const ResolvedScene&, Backend)>;

struct ViewOptions {
  std::string scene;  // empty: the built-in small dam break
  std::vector<std::string> sets;
  std::string backend = "auto";
  int frames = 0;          // > 0: run this many frames, then exit
  std::string screenshot;  // with frames: the window's last frame as PNG
  // > 0: this many SPH steps per frame; 0: real-time playback, each frame
  // advancing the simulation by the wall time of the one before, at most
  // max_sim_per_frame seconds, in steps taking at most that much wall time
  // (switchable in the panel).
  int substeps = 0;
  double max_sim_per_frame = 1.0 / 30.0;
  int resize_w = 0, resize_h = 0;  // > 0: resize the window to this after the first frame (tests)
  // The solver; empty: the scene's own (make_solver). A run over several
  // ranks gives rank 0's (dist/driven.h), whose particles the viewer reads
  // after a gather (Solver::gather_frame) at each frame that stepped.
  ViewSolverMaker make_solver;
};

// Whether this sphray was built with the viewer (GLFW, GLEW, Dear ImGui found).
bool viewer_built();
// Runs the window until closed (or `frames` frames). Throws on a bad scene or
// when no display can be opened.
int run_viewer(const ViewOptions& opt, std::ostream& log);

// The built-in scene of `sphray view` without a scene file: a small dam break
// that the CPU backend runs at interactive rates.
const char* small_view_scene();

// The scene the viewer shows: opt.scene with opt.sets, or the built-in one.
ResolvedScene resolve_view_scene(const ViewOptions& opt);

}  // namespace sphray
