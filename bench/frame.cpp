#include "frame.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <ostream>
#include <stdexcept>

#include "sim.h"
#include "field.h"
#include "pipeline/pipeline.h"
#include "render/image.h"
#include "render/render.h"
#include "io/scene.h"

namespace sphray {

namespace {

// The bench field scene of one size, with the render settings applied.
Scene frame_scene(size_t target, int width, int height, int interfaces, std::vector<std::string> overrides) {
  const int volume = default_bench_volume(target);
  overrides.insert(overrides.begin(), {"render.width=" + std::to_string(width), "render.height=" + std::to_string(height),
                                       "render.interfaces=" + std::to_string(interfaces)});
  return parse_scene(bench_field_scene(target, volume), "bench_frame", overrides);
}

std::string png_path(const std::string& dir, const std::string& name) {
  std::filesystem::create_directories(dir);
  return (std::filesystem::path(dir) / name).string();
}

}  // namespace

std::vector<BenchFrameRow> bench_frame(Backend b, const BenchFrameOptions& opt, std::ostream& log) {
  std::vector<BenchFrameRow> rows;
  for (size_t target : opt.sizes) {
    const ResolvedScene rs = resolve_scene(frame_scene(target, opt.width, opt.height, opt.interfaces, opt.overrides));
    const Scene& s = rs.scene;
    const FieldKind kind = opt.builder.empty() ? s.field.builder : parse_field_kind(opt.builder);
    const bool with_field = method_needs_field(s.render.method);  // screen_space draws the particles
    const bool presence = with_field && field_needs_presence_step(s, kind, s.field.kernel == FieldKernel::Anisotropic);
    const StageNeeds needs{presence ? PresenceMode::AtUntil : PresenceMode::Off, true};
    auto solver = make_solver(rs, b, needs);
    const FieldSetup fs = make_field_setup(rs);  // the environment's frame, with or without a field
    auto field = with_field ? make_field_builder(b, fs, kind) : nullptr;
    auto renderer = make_renderer(b);
    renderer->set_obstacles(drawn_obstacles(obstacle_meshes(s), *solver));
    simulate_collapse(s, *solver, opt.collapse, log);
    const Camera cam = make_camera(s.tank, s.render);
    const Environment env = make_environment(s.tank, fs.geom, cam);
    std::vector<double> sim, fld, ren, tot, wall, steps;
    double prev_wall_s = 0, sim_advanced = 0, wall_sum_s = 0;
    for (int f = 0; f < opt.warmup + opt.frames; ++f) {
      const auto t0 = std::chrono::steady_clock::now();
      const double t_before = solver->time();
      const uint64_t steps_before = solver->steps();
      const double sim_ms =
          opt.realtime ? advance_to(*solver, playback_target(t_before, prev_wall_s, opt.max_sim_per_frame, 1e30),
                                    presence, opt.max_sim_per_frame)
                             .ms
                       : advance_frame(*solver, opt.substeps, presence, 1e30);
      const ParticleView pv = solver->view();
      if (with_field) field->build(pv);
      show_skins(*solver, *renderer);
      renderer->render(RenderInput{with_field ? field->data() : nullptr, &fs, pv, s.sph.spacing, solver->time()}, cam, env,
                       s.render);
      const double w = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      prev_wall_s = 1e-3 * w;
      if (f < opt.warmup) continue;
      steps.push_back(double(solver->steps() - steps_before));
      sim_advanced += solver->time() - t_before;
      wall_sum_s += 1e-3 * w;
      sim.push_back(sim_ms);
      const double field_ms = with_field ? field->last_ms() : 0.0;
      fld.push_back(field_ms);
      ren.push_back(renderer->last_ms());
      tot.push_back(sim_ms + field_ms + renderer->last_ms());
      wall.push_back(w);
    }
    BenchFrameRow r;
    r.particles = solver->num_fluid();
    r.nx = fs.geom.nx; r.ny = fs.geom.ny; r.nz = fs.geom.nz;
    r.width = opt.width; r.height = opt.height; r.interfaces = opt.interfaces; r.substeps = opt.substeps;
    r.builder = field_kind_name(kind);
    r.sim_ms = median(sim); r.field_ms = median(fld); r.render_ms = median(ren);
    r.total_ms = median(tot); r.wall_ms = median(wall);
    r.fps = r.wall_ms > 0 ? 1000.0 / r.wall_ms : 0;
    r.realtime = opt.realtime;
    r.steps = median(steps);
    r.realtime_factor = wall_sum_s > 0 ? sim_advanced / wall_sum_s : 0;
    log << "    sim " << std::fixed << std::setprecision(3) << r.sim_ms << " ms, field " << r.field_ms << " ms, render "
        << r.render_ms << " ms, frame wall " << r.wall_ms << " ms (" << std::setprecision(1) << r.fps << " fps, "
        << std::setprecision(3) << r.steps << " steps a frame, x" << r.realtime_factor << " real time)\n"
        << std::defaultfloat;
    if (!opt.png_dir.empty())
      write_png(png_path(opt.png_dir, "bench_frame_" + std::to_string(target) + ".png"), renderer->download());
    rows.push_back(r);
  }
  return rows;
}

nlohmann::json to_json(const std::vector<BenchFrameRow>& rows, Backend b, const BenchFrameOptions& opt) {
  nlohmann::json j = bench_json("frame", b,
                                "median ms per frame (stages: device events; wall: host clock around the frame)",
                                opt.overrides);
  j["warmup_frames"] = opt.warmup;
  j["measured_frames"] = opt.frames;
  j["collapse_T"] = opt.collapse;
  j["rows"] = nlohmann::json::array();
  for (const auto& r : rows)
    j["rows"].push_back({{"particles", r.particles}, {"volume", {r.nx, r.ny, r.nz}}, {"width", r.width},
                         {"height", r.height}, {"interfaces", r.interfaces}, {"substeps", r.substeps},
                         {"builder", r.builder}, {"sim_ms", r.sim_ms}, {"field_ms", r.field_ms},
                         {"render_ms", r.render_ms}, {"stages_ms", r.total_ms}, {"wall_ms", r.wall_ms}, {"fps", r.fps},
                         {"realtime", r.realtime}, {"steps_per_frame", r.steps},
                         {"realtime_factor", r.realtime_factor}});
  return j;
}

void print_table(const std::vector<BenchFrameRow>& rows, std::ostream& out) {
  out << std::setw(9) << "particles" << std::setw(13) << "volume" << std::setw(11) << "image" << std::setw(5) << "N"
      << std::setw(5) << "sub" << std::setw(10) << "builder" << std::setw(9) << "sim" << std::setw(9) << "field"
      << std::setw(9) << "render" << std::setw(9) << "stages" << std::setw(9) << "wall" << std::setw(8) << "fps"
      << std::setw(7) << "steps" << std::setw(9) << "x real" << "   (median ms per frame; x real: simulated / wall)\n";
  for (const auto& r : rows) {
    const std::string vol = std::to_string(r.nx) + "x" + std::to_string(r.ny) + "x" + std::to_string(r.nz);
    const std::string img = std::to_string(r.width) + "x" + std::to_string(r.height);
    out << std::setw(9) << r.particles << std::setw(13) << vol << std::setw(11) << img << std::setw(5) << r.interfaces
        << std::setw(5) << r.substeps << std::setw(10) << r.builder << std::fixed << std::setprecision(3)
        << std::setw(9) << r.sim_ms << std::setw(9) << r.field_ms << std::setw(9) << r.render_ms << std::setw(9)
        << r.total_ms << std::setw(9) << r.wall_ms << std::setprecision(1) << std::setw(8) << r.fps
        << std::setprecision(0) << std::setw(7) << r.steps << std::setprecision(3) << std::setw(9)
        << r.realtime_factor << "\n"
        << std::defaultfloat;
  }
}

std::vector<BenchRenderRow> bench_render(Backend b, const BenchRenderOptions& opt, std::ostream& log) {
  for (const auto& m : opt.methods) parse_render_method(m);  // an unknown one fails before any work
  if (opt.scene != "dam_break" && opt.scene != "pool")
    throw std::invalid_argument("--scene '" + opt.scene + "': dam_break or pool");
  const bool pool = opt.scene == "pool";
  const int volume = default_bench_volume(opt.particles);
  std::vector<std::string> sets = opt.overrides;
  sets.insert(sets.begin(), {"render.width=" + std::to_string(opt.width), "render.height=" + std::to_string(opt.height)});
  const ResolvedScene rs = resolve_scene(parse_scene(
      pool ? bench_pool_scene(opt.particles, volume) : bench_field_scene(opt.particles, volume), "bench_render", sets));
  const Scene& s = rs.scene;
  const StageNeeds needs{PresenceMode::AtUntil, true};
  auto solver = make_solver(rs, b, needs);
  const FieldSetup fs = make_field_setup(rs);
  auto field = make_field_builder(b, fs, FieldKind::Naive);
  auto renderer = make_renderer(b);
  if (pool) {
    log << "  " << solver->num_fluid() << " particles: a still pool (the start lattice)\n";
    solver->set_presence(PresenceMode::AtUntil);
    solver->step(solver->time() + 1e-5);  // one short step: presence, as the frames of a run have it
  } else {
    simulate_collapse(s, *solver, opt.collapse, log);
  }
  const ParticleView pv = solver->view();
  const Camera cam = make_camera(s.tank, s.render);
  const Environment env = make_environment(s.tank, fs.geom, cam);
  const double spacing = s.sph.spacing;

  // Every branch to 8 interfaces: at most 255 interfaces per pixel, no weight cut.
  RenderSettings ref = s.render;
  ref.method = RenderMethod::Raycast;
  ref.step = float(opt.reference_step);
  ref.interfaces = 8;
  ref.reflections = true;
  ref.budget = 255;
  ref.min_weight = 0;
  field->build(pv);
  renderer->render(field->data(), fs, cam, env, ref);
  const Image reference = renderer->download();
  log << "  reference: naive field, step " << ref.step << " voxels, every branch to 8 interfaces, "
      << renderer->last_ms() << " ms\n";
  if (!opt.png_dir.empty()) write_png(png_path(opt.png_dir, "render_reference.png"), reference);

  // One setting: its median render time and stages, its image and error.
  auto measure = [&](BenchRenderRow r, const RenderSettings& set, bool with_field, const std::string& png) {
    std::vector<double> ms;
    std::vector<std::vector<double>> stage_ms;
    const RenderInput in{with_field ? field->data() : nullptr, &fs, pv, spacing};
    for (int k = 0; k < opt.warmup + opt.frames; ++k) {
      renderer->render(in, cam, env, set);
      if (k < opt.warmup) continue;
      ms.push_back(renderer->last_ms());
      const auto st = renderer->last_stages();
      stage_ms.resize(st.size());
      for (size_t i = 0; i < st.size(); ++i) stage_ms[i].push_back(st[i].second);
    }
    const auto names = renderer->last_stages();
    for (size_t i = 0; i < names.size(); ++i) r.stages_ms.emplace_back(names[i].first, median(stage_ms[i]));
    const Image img = renderer->download();
    r.render_ms = median(ms);
    r.psnr_db = psnr(reference, img);
    r.ssim = ssim(reference, img);
    if (!opt.png_dir.empty() && !png.empty()) write_png(png_path(opt.png_dir, png), img);
    log << "    " << r.method << (r.builder.empty() ? "" : " " + r.builder);
    if (r.method == "raycast") log << " step " << r.step << " N " << r.interfaces << " budget " << r.budget;
    if (r.method == "slices") log << " " << r.slices << " slices";
    if (r.method == "screen_space") log << " filter " << set.filter_width << " x " << r.filter_iterations;
    log << ": " << std::fixed << std::setprecision(3) << r.render_ms << " ms, PSNR " << std::setprecision(2)
        << r.psnr_db << " dB, SSIM " << std::setprecision(4) << r.ssim << "\n" << std::defaultfloat;
    return r;
  };
  auto has = [&](const char* m) { return std::find(opt.methods.begin(), opt.methods.end(), m) != opt.methods.end(); };

  std::vector<BenchRenderRow> rows;
  for (FieldKind kind : {FieldKind::Naive, FieldKind::Presence}) {
    if (!has("raycast") && !(has("slices") && kind == FieldKind::Presence)) continue;
    if (field->kind() != kind) field = make_field_builder(b, fs, kind);
    std::vector<double> fms;
    for (int k = 0; k < opt.warmup + opt.frames; ++k) {
      field->build(pv);
      if (k >= opt.warmup) fms.push_back(field->last_ms());
    }
    BenchRenderRow base;
    base.builder = field_kind_name(kind);
    base.field_ms = median(fms);
    if (has("raycast"))
      for (double step : opt.steps)
        for (int n : opt.interfaces)
          for (int budget : opt.budgets) {
            RenderSettings set = s.render;
            set.method = RenderMethod::Raycast;
            set.step = float(step);
            set.interfaces = n;
            set.reflections = budget > 0;
            if (budget > 0) set.budget = budget;
            set.min_weight = opt.min_weight;
            BenchRenderRow r = base;
            r.method = "raycast";
            r.step = step;
            r.interfaces = n;
            r.budget = budget;
            // the default settings' image, and the same without reflections
            const bool dflt = kind == FieldKind::Presence && step == 0.5 && n == 4;
            const std::string png = !dflt ? ""
                                    : budget == 0 ? "render_no_reflections.png"
                                    : budget == s.render.budget ? "render_default.png"
                                                                : "";
            rows.push_back(measure(r, set, true, png));
          }
    if (has("slices") && kind == FieldKind::Presence)
      for (int count : opt.slices) {
        RenderSettings set = s.render;
        set.method = RenderMethod::Slices;
        set.slices = count;
        BenchRenderRow r = base;
        r.method = "slices";
        r.interfaces = set.interfaces;
        r.budget = set.reflections ? set.budget : 0;
        r.slices = count;
        rows.push_back(measure(r, set, true, count == s.render.slices ? "render_slices.png" : ""));
      }
  }
  if (has("screen_space"))
    for (int it : opt.filter_iterations) {
      RenderSettings set = s.render;
      set.method = RenderMethod::ScreenSpace;
      set.filter_iterations = it;
      BenchRenderRow r;
      r.method = "screen_space";
      r.interfaces = 2;
      r.filter_iterations = it;
      rows.push_back(measure(r, set, false, it == s.render.filter_iterations ? "render_screen_space.png" : ""));
    }
  return rows;
}

nlohmann::json to_json(const std::vector<BenchRenderRow>& rows, Backend b, const BenchRenderOptions& opt) {
  nlohmann::json j = bench_json("render", b,
                                "median ms (device events); PSNR over R, G, B in dB and SSIM of the luma, against "
                                "the reference",
                                opt.overrides);
  j["particles"] = opt.particles;
  j["scene"] = opt.scene;
  j["image"] = {opt.width, opt.height};
  j["reference"] = {{"method", "raycast"}, {"builder", "naive"}, {"step_voxels", opt.reference_step},
                    {"interfaces", 8}, {"branches", "all (budget 255, no weight cut)"}};
  j["min_weight"] = opt.min_weight;
  j["warmup_renders"] = opt.warmup;
  j["measured_renders"] = opt.frames;
  if (opt.scene == "dam_break") j["collapse_T"] = opt.collapse;
  j["rows"] = nlohmann::json::array();
  for (const auto& r : rows) {
    nlohmann::json stages = nlohmann::json::object();
    for (const auto& st : r.stages_ms) stages[st.first] = st.second;
    j["rows"].push_back({{"method", r.method}, {"builder", r.builder}, {"step_voxels", r.step},
                         {"interfaces", r.interfaces}, {"budget", r.budget},
                         {"filter_iterations", r.filter_iterations}, {"slices", r.slices},
                         {"render_ms", r.render_ms}, {"stages_ms", stages}, {"field_ms", r.field_ms},
                         {"psnr_db", std::isinf(r.psnr_db) ? nlohmann::json("inf") : nlohmann::json(r.psnr_db)},
                         {"ssim", r.ssim}});
  }
  return j;
}

void print_table(const std::vector<BenchRenderRow>& rows, std::ostream& out) {
  out << std::setw(13) << "method" << std::setw(10) << "builder" << std::setw(18) << "setting" << std::setw(10)
      << "field ms" << std::setw(11) << "render ms" << std::setw(10) << "PSNR dB" << std::setw(8) << "SSIM\n";
  for (const auto& r : rows) {
    std::string setting;
    if (r.method == "raycast")
      setting = "step " + std::to_string(r.step).substr(0, 4) + " N" + std::to_string(r.interfaces) + " b" +
                std::to_string(r.budget);
    else if (r.method == "slices") setting = std::to_string(r.slices) + " slices";
    else setting = std::to_string(r.filter_iterations) + " passes";
    out << std::setw(13) << r.method << std::setw(10) << r.builder << std::setw(18) << setting << std::fixed
        << std::setprecision(3) << std::setw(10) << r.field_ms << std::setw(11) << r.render_ms << std::setprecision(2)
        << std::setw(10) << r.psnr_db << std::setprecision(4) << std::setw(8) << r.ssim << "\n" << std::defaultfloat;
  }
}

}  // namespace sphray
