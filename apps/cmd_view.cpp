// `sphray view [SCENE]`: the real-time viewer (viewer/).
#include <iostream>
#include <tuple>

#include "cli.h"
#include "commands.h"
#include "viewer/viewer.h"

namespace sphray::cli {

CLI::App* add_view_command(CLI::App& app, int& exit_code) {
  struct Args {
    ViewOptions view;
    FrameArgs frames;
    std::string resize;
  };
  auto a = std::make_shared<Args>();
  auto* view = app.add_subcommand("view", "the real-time dam break in a window (GLFW + OpenGL, Dear ImGui panel)");
  view->add_option("scene", a->view.scene, "scene JSON file (default: a built-in small dam break)");
  view->add_option("--backend", a->view.backend, "auto | cpu | cuda");
  view->add_option("--set", a->view.sets, "override a scene value, e.g. --set render.interfaces=8");
  view->add_option("--size", a->frames.size, "raycast image (and window) size WIDTHxHEIGHT");
  view->add_option("--substeps", a->view.substeps,
                   "SPH steps per frame instead of real-time playback (changeable in the panel)")
      ->check(CLI::Range(1, 20));
  view->add_option("--frames", a->view.frames, "run this many frames, then exit")->check(CLI::Range(1, 1000000));
  view->add_option("--screenshot", a->view.screenshot, "with --frames: write the window's last frame as PNG");
  view->add_option("--resize", a->resize, "after the first frame, resize the window to WIDTHxHEIGHT (the image follows)");
  view->callback([a, &exit_code] {
    ViewOptions& v = a->view;
    if (!v.screenshot.empty() && v.frames == 0) throw std::runtime_error("--screenshot needs --frames N");
    if (!v.screenshot.empty()) {
      check_not_other_image(v.screenshot, "--screenshot");
      check_writable(v.screenshot, "--screenshot");
    }
    add_frame_overrides(a->frames, v.sets);
    if (!a->resize.empty()) {
      std::tie(v.resize_w, v.resize_h) = parse_wxh(a->resize, "--resize");
      if (v.resize_w < 16 || v.resize_h < 16 || v.resize_w > 8192 || v.resize_h > 8192)
        throw std::runtime_error("--resize '" + a->resize + "': each side must be 16 to 8192 pixels");
    }
    exit_code = run_viewer(v, std::cout);
  });
  return view;
}

}  // namespace sphray::cli
