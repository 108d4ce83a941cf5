// `sphray render`: one frame or a sequence to PNG, from a scene (simulated
// to the time asked for) or from an HDF5 export (its particles re-rendered).
#include <fstream>
#include <iostream>
#include <sstream>

#include "cli.h"
#include "commands.h"
#include "io/frames_h5.h"
#include "pipeline/pipeline.h"
#include "pipeline/setup.h"
#include "pipeline/sinks.h"
#include "sph/skin.h"

namespace sphray::cli {

namespace {

struct RenderArgs {
  std::string scene, from, out;
  double time = -1;  // scene: render the state at this time (default: run.end_time)
  int frame = -1;    // --from: this frame of the file (default: all)
};

// `sphray render SCENE --out x.png [--time T]`: one frame at time T;
// `sphray render SCENE --out DIR`: every output frame (as run --frames-dir).
int render_scene(const RenderArgs& ra, const std::string& backend_arg, std::vector<std::string> sets) {
  check_not_other_image(ra.out, "--out", ", or a directory for a sequence");
  check_distinct_files({{"scene file", ra.scene}, {"--out", ra.out}});
  const bool single = is_png_path(ra.out);
  if (single && ra.time >= 0) {
    std::ostringstream t;
    t.precision(17);
    t << ra.time;
    sets.push_back("run.end_time=" + t.str());
  }
  Scene scene = load_scene(ra.scene, sets);
  if (single) {
    check_writable(ra.out);
    if (scene.run.end_time > 0) scene.run.output_interval = scene.run.end_time;  // frames 0 and 1 (the end)
  }
  const ResolvedScene rs = resolve_scene(scene);
  const Backend b = choose_backend(backend_arg, std::cout);
  // A directory: every render.frames_every-th output frame; one image: the
  // state at the end (frame 1; frame 0 when the scene ends at t = 0).
  PngSink png(single ? "" : ra.out, scene.render, "--out");
  const int last = scene.run.end_time > 0 ? 1 : 0;
  const bool needs_field = method_needs_field(scene.render.method);
  FunctionSink one(
      [&](const Solver& s, const FieldBuilder* f, int) {
        png.draw_skins(s);
        png.frames().render_to(s.view(), f, ra.out, s.time());
      },
                   FrameNeeds{needs_field, false}, [last](int f) { return f == last; });
  OutputSink* sink = single ? static_cast<OutputSink*>(&one) : &png;
  const StageNeeds needs = needs_of(scene, {sink});
  auto solver = make_solver(rs, b, needs);
  auto field = make_field(rs, b, needs);
  png.open(scene, b, make_field_setup(rs));
  FrameRenderer& frames = png.frames();
  RunOptions opt;
  opt.field = field.get();
  opt.sinks = {sink};
  std::cout << "rendering scene " << scene.name << " (" << solver->num_fluid() << " particles) to "
            << (single ? "t = " + std::to_string(scene.run.end_time) + " s" : "every output frame") << "\n";
  const RunSummary r = run_scene(scene, *solver, opt, std::cout);
  frames.finish();  // the last PNGs are still being written
  print_summary(r, std::cout);
  std::cout << "  frames         " << frames.frames_written() << " PNG" << (frames.frames_written() == 1 ? "" : "s")
            << " to " << ra.out << ", " << frames.mean_render_ms() << " ms per render\n";
  return 0;
}

// A run keeps every particle inside its grid (the tank, its wall layers and,
// with an open top, the headroom above it), so a position beyond it in a
// frame file means another tank (a --set tank.* on render) or a file edited
// elsewhere. Refused by name: the grid's key and the field's splat would
// convert it to an integer cell out of range.
void check_in_grid(const GridGeom& g, const Float4& p, const std::string& file, size_t frame, size_t i) {
  const float x[3] = {p.x, p.y, p.z}, lo[3] = {g.origin.x, g.origin.y, g.origin.z};
  const float hi[3] = {lo[0] + float(g.nx) * g.cell_size, lo[1] + float(g.ny) * g.cell_size,
                       lo[2] + float(g.nz) * g.cell_size};
  for (int a = 0; a < 3; ++a)
    if (!(x[a] >= lo[a] && x[a] < hi[a])) {
      std::ostringstream os;
      os << "--from '" << file << "': frame " << frame << ", particle " << i << " at (" << p.x << ", " << p.y << ", "
         << p.z << ") m is outside the scene's domain, x " << lo[0] << " .. " << hi[0] << ", y " << lo[1] << " .. "
         << hi[1] << ", z " << lo[2] << " .. " << hi[2] << " m (the tank with its walls): the file was written for "
         << "another tank (a --set tank.* here?)";
      throw std::runtime_error(os.str());
    }
}

// `sphray render --from out.h5 --out DIR|x.png [--frame K]`: the exported
// particles, their field rebuilt on the chosen backend, rendered.
int render_file(const RenderArgs& ra, const std::string& backend_arg, const std::vector<std::string>& sets) {
  check_not_other_image(ra.out, "--out", ", or a directory for a sequence");
  check_distinct_files({{"--from file", ra.from}, {"--out", ra.out}});
  const FrameReader reader(ra.from);
  const Scene scene = parse_scene(reader.header().scene_json, ra.from + " (its scene)", sets);
  const size_t n = reader.frames().size();
  if (n == 0) throw std::runtime_error("--from '" + ra.from + "': the file holds no frames");
  if (ra.frame >= 0 && size_t(ra.frame) >= n)
    throw std::runtime_error("--frame " + std::to_string(ra.frame) + ": '" + ra.from + "' holds frames 0 .. " +
                             std::to_string(n - 1));
  const bool single = is_png_path(ra.out);
  if (single && ra.frame < 0 && n > 1)
    throw std::runtime_error("--out '" + ra.out + "' is one image but '" + ra.from + "' holds " + std::to_string(n) +
                             " frames: give --frame K, or a directory");
  if (single) check_writable(ra.out);
  const Backend b = choose_backend(backend_arg, std::cout);
  const ResolvedScene rs = resolve_scene(scene);
  const FieldSetup fs = make_field_setup(rs);
  const bool needs_field = method_needs_field(scene.render.method);
  auto field = needs_field ? make_field_builder(b, fs, scene.field.builder) : nullptr;
  FrameRenderer frames(scene.render, scene.tank, scene.sph.spacing, b, fs, single ? "" : ra.out, "--out");
  // Skinned obstacles are drawn displaced by the heights the frames carry
  // (a frame without them: at rest).
  std::vector<SkinGeometry> skins;
  for (const SkinInput& k : skin_inputs(scene)) skins.push_back(make_skin_geometry(k));
  frames.set_obstacles(drawn_obstacles(obstacle_meshes(scene), skins));
  const size_t first = ra.frame >= 0 ? size_t(ra.frame) : 0, end = ra.frame >= 0 ? first + 1 : n;
  for (size_t k = first; k < end; ++k) {
    const Frame f = reader.read(k);
    for (const SkinGeometry& g : skins) {
      std::vector<float> h(g.map.size(), 0.0f);
      for (const Frame::Skin& fk : f.skins)
        if (fk.obstacle == g.input.obstacle) {
          if (fk.height.size() != h.size())
            throw std::runtime_error("--from '" + ra.from + "': frame " + std::to_string(k) + " holds " +
                                     std::to_string(fk.height.size()) + " heights for obstacle " +
                                     std::to_string(fk.obstacle) + "'s skin, its scene " + std::to_string(h.size()));
          h = fk.height;
        }
      frames.renderer().set_obstacle_vertices(g.input.obstacle, displaced_surface(g, h));
    }
    SolverInput in = make_solver_input(rs, PresenceMode::Off);
    in.skins.clear();  // drawn from the file's heights; nothing steps here
    const float rho0 = float(scene.sph.rest_density);
    in.fluid_pos_rho.resize(f.count());
    for (size_t i = 0; i < f.count(); ++i) {
      in.fluid_pos_rho[i] = {f.position[3 * i], f.position[3 * i + 1], f.position[3 * i + 2], rho0};
      check_in_grid(in.grid, in.fluid_pos_rho[i], ra.from, k, i);
    }
    in.fluid_vel.assign(f.count(), Float4{0, 0, 0, 0});
    auto solver = b == Backend::Cuda ? make_cuda_solver(in) : make_cpu_solver(in);  // sorts them into the grid
    // exported presence is in the file's order, not the grid's: the presence
    // builder uses full extents (its field then classifies as naive's)
    if (needs_field) field->build(solver->view());
    if (single) frames.render_to(solver->view(), field.get(), ra.out, f.time);
    else frames.write_frame(solver->view(), field.get(), int(k), f.time);
    std::cout << "  frame " << k << " (t = " << f.time << " s, " << f.count() << " particles)";
    if (needs_field) std::cout << ": field " << field->last_ms() << " ms";
    std::cout << "\n";
  }
  frames.finish();
  std::cout << "rendered " << frames.frames_written() << " frame" << (frames.frames_written() == 1 ? "" : "s")
            << " of " << ra.from << " to " << ra.out << ", " << frames.mean_render_ms() << " ms per render\n";
  return 0;
}

}  // namespace

CLI::App* add_render_command(CLI::App& app, int& exit_code) {
  struct Args {
    RenderArgs render;
    FrameArgs frames;
    std::string backend = "auto";
    std::vector<std::string> sets;
  };
  auto a = std::make_shared<Args>();
  auto* render = app.add_subcommand("render", "render one frame or a sequence to PNG, from a scene or an HDF5 export");
  render->add_option("scene", a->render.scene, "scene JSON file, or an HDF5 export (as --from FILE)");
  render->add_option("--from", a->render.from, "an HDF5 file written by sphray run --export");
  render->add_option("--out", a->render.out, "x.png: one image; otherwise a directory for frame_NNNNNN.png")
      ->required();
  render->add_option("--time", a->render.time, "scene: simulate to this time and render it (default run.end_time)")
      ->check(CLI::Range(0.0, 1e6));
  render->add_option("--frame", a->render.frame, "--from: render this frame only (default: all)")
      ->check(CLI::Range(0, 100000000));
  render->add_option("--backend", a->backend, "auto | cpu | cuda");
  render->add_option("--set", a->sets, "override a scene value, e.g. --set render.interfaces=8");
  render->add_option("--size", a->frames.size, "image size WIDTHxHEIGHT");
  render->add_option("--frames-every", a->frames.every, "a directory --out: every K-th output frame")
      ->check(CLI::Range(1, 1000000));
  render->callback([a, &exit_code] {
    RenderArgs& ra = a->render;
    if (!ra.scene.empty() && ra.from.empty()) {  // an export given where a scene goes
      std::ifstream f(ra.scene, std::ios::binary);
      std::string head(8, '\0');
      if (f.read(&head[0], 8) && is_hdf5_signature(head)) std::swap(ra.scene, ra.from);
    }
    if (ra.scene.empty() == ra.from.empty()) throw std::runtime_error("render: give either a scene file or --from FILE.h5");
    if (!ra.from.empty() && ra.time >= 0) throw std::runtime_error("--time applies to a scene, not --from");
    if (ra.from.empty() && ra.frame >= 0) throw std::runtime_error("--frame applies to --from FILE");
    add_frame_overrides(a->frames, a->sets);
    exit_code = ra.from.empty() ? render_scene(ra, a->backend, a->sets) : render_file(ra, a->backend, a->sets);
  });
  return render;
}

}  // namespace sphray::cli
