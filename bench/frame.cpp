#include "frame.h"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <ostream>
#include <stdexcept>

#include "sim.h"
#include "field.h"
#include "pipeline/pipeline.h"
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
  const FieldKind kind = parse_field_kind(opt.builder);
  for (size_t target : opt.sizes) {
    const ResolvedScene rs = resolve_scene(frame_scene(target, opt.width, opt.height, opt.interfaces, opt.overrides));
    const Scene& s = rs.scene;
    const StageNeeds needs{kind == FieldKind::Presence ? PresenceMode::AtUntil : PresenceMode::Off, true};
    auto solver = make_solver(rs, b, needs);
    auto field = make_field_builder(b, make_field_setup(rs), kind);
    auto renderer = make_renderer(b);
    simulate_collapse(s, *solver, opt.collapse, log);
    const Camera cam = make_camera(s.tank, s.render);
    const Environment env = make_environment(s.tank, field->setup().geom, cam);
    std::vector<double> sim, fld, ren, tot, wall, steps;
    double prev_wall_s = 0, sim_advanced = 0, wall_sum_s = 0;
    for (int f = 0; f < opt.warmup + opt.frames; ++f) {
      const auto t0 = std::chrono::steady_clock::now();
      const double t_before = solver->time();
      const uint64_t steps_before = solver->steps();
      const double sim_ms =
          opt.realtime ? advance_to(*solver, playback_target(t_before, prev_wall_s, opt.max_sim_per_frame, 1e30),
                                    kind == FieldKind::Presence, opt.max_sim_per_frame)
                             .ms
                       : advance_frame(*solver, opt.substeps, kind == FieldKind::Presence, 1e30);
      const ParticleView pv = solver->view();
      field->build(pv);
      renderer->render(field->data(), field->setup(), cam, env, s.render);
      const double w = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      prev_wall_s = 1e-3 * w;
      if (f < opt.warmup) continue;
      steps.push_back(double(solver->steps() - steps_before));
      sim_advanced += solver->time() - t_before;
      wall_sum_s += 1e-3 * w;
      sim.push_back(sim_ms);
      fld.push_back(field->last_ms());
      ren.push_back(renderer->last_ms());
      tot.push_back(sim_ms + field->last_ms() + renderer->last_ms());
      wall.push_back(w);
    }
    BenchFrameRow r;
    r.particles = solver->num_fluid();
    r.nx = field->setup().geom.nx; r.ny = field->setup().geom.ny; r.nz = field->setup().geom.nz;
    r.width = opt.width; r.height = opt.height; r.interfaces = opt.interfaces; r.substeps = opt.substeps;
    r.builder = opt.builder;
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
  const ResolvedScene rs = resolve_scene(frame_scene(opt.particles, opt.width, opt.height, 8, opt.overrides));
  const Scene& s = rs.scene;
  const StageNeeds needs{PresenceMode::AtUntil, true};
  auto solver = make_solver(rs, b, needs);
  const FieldSetup fs = make_field_setup(rs);
  auto field = make_field_builder(b, fs, FieldKind::Naive);
  auto renderer = make_renderer(b);
  simulate_collapse(s, *solver, opt.collapse, log);
  const ParticleView pv = solver->view();
  const Camera cam = make_camera(s.tank, s.render);
  const Environment env = make_environment(s.tank, field->setup().geom, cam);

  // Every branch to 8 interfaces: at most 255 interfaces per pixel, no weight cut.
  RenderSettings ref = s.render;
  ref.step = float(opt.reference_step);
  ref.interfaces = 8;
  ref.reflections = true;
  ref.budget = 255;
  ref.min_weight = 0;
  field->build(pv);
  renderer->render(field->data(), field->setup(), cam, env, ref);
  const Image reference = renderer->download();
  log << "  reference: naive field, step " << ref.step << " voxels, every branch to 8 interfaces, "
      << renderer->last_ms() << " ms\n";
  if (!opt.png_dir.empty()) write_png(png_path(opt.png_dir, "render_reference.png"), reference);

  std::vector<BenchRenderRow> rows;
  for (FieldKind kind : {FieldKind::Naive, FieldKind::Presence}) {
    if (field->kind() != kind) field = make_field_builder(b, fs, kind);
    std::vector<double> fms;
    for (int k = 0; k < opt.warmup + opt.frames; ++k) {
      field->build(pv);
      if (k >= opt.warmup) fms.push_back(field->last_ms());
    }
    for (double step : opt.steps)
      for (int n : opt.interfaces)
        for (int budget : opt.budgets) {
          RenderSettings rs = s.render;
          rs.step = float(step);
          rs.interfaces = n;
          rs.reflections = budget > 0;
          if (budget > 0) rs.budget = budget;
          rs.min_weight = opt.min_weight;
          std::vector<double> ms;
          for (int k = 0; k < opt.warmup + opt.frames; ++k) {
            renderer->render(field->data(), field->setup(), cam, env, rs);
            if (k >= opt.warmup) ms.push_back(renderer->last_ms());
          }
          const Image img = renderer->download();
          BenchRenderRow r{field_kind_name(kind), step, n, budget, median(ms), median(fms), psnr(reference, img)};
          // the default settings' image, and the same without reflections
          if (!opt.png_dir.empty() && kind == FieldKind::Presence && step == 0.5 && n == 4 &&
              (budget == 0 || budget == s.render.budget))
            write_png(png_path(opt.png_dir, budget == 0 ? "render_no_reflections.png" : "render_default.png"), img);
          log << "    " << r.builder << " step " << step << " N " << n << " budget " << budget << ": " << std::fixed
              << std::setprecision(3) << r.render_ms << " ms, PSNR " << std::setprecision(2) << r.psnr_db << " dB\n"
              << std::defaultfloat;
          rows.push_back(r);
        }
  }
  return rows;
}

nlohmann::json to_json(const std::vector<BenchRenderRow>& rows, Backend b, const BenchRenderOptions& opt) {
  nlohmann::json j = bench_json("render", b, "median ms (device events); PSNR over R, G, B in dB", opt.overrides);
  j["particles"] = opt.particles;
  j["image"] = {opt.width, opt.height};
  j["reference"] = {{"builder", "naive"}, {"step_voxels", opt.reference_step}, {"interfaces", 8},
                    {"branches", "all (budget 255, no weight cut)"}};
  j["min_weight"] = opt.min_weight;
  j["warmup_renders"] = opt.warmup;
  j["measured_renders"] = opt.frames;
  j["rows"] = nlohmann::json::array();
  for (const auto& r : rows)
    j["rows"].push_back({{"builder", r.builder}, {"step_voxels", r.step}, {"interfaces", r.interfaces},
                         {"budget", r.budget}, {"render_ms", r.render_ms}, {"field_ms", r.field_ms},
                         {"psnr_db", std::isinf(r.psnr_db) ? nlohmann::json("inf") : nlohmann::json(r.psnr_db)}});
  return j;
}

void print_table(const std::vector<BenchRenderRow>& rows, std::ostream& out) {
  out << std::setw(10) << "builder" << std::setw(8) << "step" << std::setw(5) << "N" << std::setw(8) << "budget"
      << std::setw(10) << "field ms" << std::setw(11) << "render ms" << std::setw(10) << "PSNR dB\n";
  for (const auto& r : rows)
    out << std::setw(10) << r.builder << std::setw(8) << r.step << std::setw(5) << r.interfaces << std::setw(8)
        << r.budget << std::fixed << std::setprecision(3) << std::setw(10) << r.field_ms << std::setw(11) << r.render_ms
        << std::setprecision(2) << std::setw(10) << r.psnr_db << "\n" << std::defaultfloat;
}

}  // namespace sphray
