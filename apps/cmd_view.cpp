// `sphray view [SCENE]`: the real-time viewer (viewer/); under mpirun rank 0
// shows the window and drives the other ranks' slabs (dist/driven.h).
#include <iostream>
#include <tuple>

#include "cli.h"
#include "commands.h"
#include "dist/driven.h"
#include "dist/slab_solver.h"
#include "pipeline/pipeline.h"
#include "ranks.h"
#include "viewer/viewer.h"

namespace sphray::cli {

namespace {

// The viewer over the ranks of an MPI launcher: every rank makes its slab's
// solver (make_slab_solver, rank 0 with a grid of the gathered particles for
// the field and the renderer); rank 0 runs the window, telling the others
// each step, gather and reset as it makes them; they follow until it quits.
int view_over_ranks(ViewOptions v, std::ostream& log) {
  if (!viewer_built()) return run_viewer(v, log);  // the error that says why
  const std::unique_ptr<Comm> comm = run_ranks();
  const bool root = comm->rank() == 0;
  std::ostream quiet(nullptr);
  const ResolvedScene rs = resolve_view_scene(v);
  const Backend b = choose_backend(v.backend, quiet);  // the viewer reports its own choice
  pick_rank_device(b);
  const SolverMaker maker = b == Backend::Cuda ? SolverMaker(make_cuda_solver) : SolverMaker(make_cpu_solver);
  auto make = [&] {
    const SolverInput in = make_solver_input(rs, PresenceMode::Off);
    SlabOptions so;
    so.frame_view = true;
    return make_slab_solver(in, plan_slabs(in, comm->size()), *comm, b, maker, so);
  };
  if (!root) {
    serve_root(*comm, make);
    return 0;
  }
  bool first = true;
  v.make_solver = [&](const ResolvedScene&, Backend) {
    if (!first) tell_new_solver(*comm);
    first = false;
    return drive_from_root(make(), *comm);
  };
  log << "viewer: " << comm->size() << " ranks; rank 0 draws the particles it gathers each frame\n";
  const int rc = run_viewer(v, log);
  tell_quit(*comm);
  return rc;
}

}  // namespace

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
    exit_code = started_by_mpi_launcher() && launcher_size() > 1 ? view_over_ranks(v, std::cout)
                                                                  : run_viewer(v, std::cout);
  });
  return view;
}

}  // namespace sphray::cli
