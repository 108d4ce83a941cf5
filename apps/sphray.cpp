// sphray: the command line. Parses flags and calls the library; every user
// error becomes one line on stderr and exit code 2, a failed run exit code 1.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <cstdio>
#include <filesystem>
#include <set>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <tuple>
#include <utility>

#include "../src/bench.h"
#include "../src/bench_field.h"
#include "../src/export.h"
#include "../src/frames_h5.h"
#include "../src/metrics.h"
#include "../src/pipeline.h"
#include "../src/render.h"
#include "../src/viewer.h"
#include "../src/bench_frame.h"
#include "../src/scene.h"
#include "../src/setup.h"
#include "sphray_builtin_scenes.h"

using namespace sphray;

namespace {

std::vector<size_t> parse_sizes(const std::string& text) {
  std::vector<size_t> out;
  std::stringstream ss(text);
  for (std::string item; std::getline(ss, item, ',');) {
    double mult = 1;
    if (!item.empty() && (item.back() == 'k' || item.back() == 'K')) { mult = 1e3; item.pop_back(); }
    else if (!item.empty() && (item.back() == 'm' || item.back() == 'M')) { mult = 1e6; item.pop_back(); }
    size_t used = 0;
    double v = 0;
    try { v = std::stod(item, &used); } catch (...) { used = 0; }
    if (used != item.size() || !(v > 0) || v * mult > 1e9)
      throw std::runtime_error("--sizes: '" + item + "' is not a particle count (e.g. 125k,1M)");
    out.push_back(size_t(v * mult));
  }
  if (out.empty()) throw std::runtime_error("--sizes: empty list");
  return out;
}

struct ExportArgs {
  std::string path;
  int every = 1;
  std::string fields;
};

struct FrameArgs {
  std::string dir;   // --frames-dir
  std::string size;  // --size WxH
  int every = 0;     // --frames-every (0: the scene's render.frames_every)
};

// --size WxH and --frames-every as scene overrides (so the run's scene records them).
// "WIDTHxHEIGHT" -> {w, h}; the range is checked by whoever uses it.
std::pair<int, int> parse_wxh(const std::string& text, const char* option) {
  const size_t x = text.find('x');
  int w = 0, h = 0;
  size_t uw = 0, uh = 0;
  try {
    w = std::stoi(text.substr(0, x), &uw);
    h = std::stoi(text.substr(x + 1), &uh);
  } catch (...) {
    uw = 0;
  }
  if (x == std::string::npos || uw != x || uh != text.size() - x - 1)
    throw std::runtime_error(std::string(option) + " '" + text + "': must be WIDTHxHEIGHT, e.g. 1280x720");
  return {w, h};
}

void add_frame_overrides(const FrameArgs& fa, std::vector<std::string>& sets) {
  if (!fa.size.empty()) {
    const auto [w, h] = parse_wxh(fa.size, "--size");
    sets.push_back("render.width=" + std::to_string(w));
    sets.push_back("render.height=" + std::to_string(h));
  }
  if (fa.every > 0) sets.push_back("render.frames_every=" + std::to_string(fa.every));
}

// "FLAG: cannot write 'PATH': reason", the reason from errno when a write set it.
std::string write_failure(const std::string& flag, const std::string& path) {
  return flag + ": cannot write '" + path + "'" + (errno ? std::string(": ") + std::strerror(errno) : "");
}

// Opens an output file before the work that fills it, so that a bad path
// fails at once (bad input, exit 2).
std::ofstream open_output(const std::string& flag, const std::string& path) {
  errno = 0;
  std::ofstream f(path);
  if (!f) throw std::runtime_error(write_failure(flag, path));
  return f;
}

// Writes j and closes the file, checking both: an ofstream's write error
// shows only when its buffer reaches the disk, here at close.
void write_json(std::ofstream& f, const nlohmann::json& j, const std::string& flag, const std::string& path) {
  errno = 0;
  f << j.dump(2) << "\n";
  f.close();
  if (!f) throw OutputError(write_failure(flag, path));
}

// The files a command writes must be neither its input nor each other: `run
// dam.json --export dam.json` replaced the scene with the export, and two
// outputs on one path would interleave. Each pair is {flag, path}; the first
// is the input. Paths compare after resolving symbolic links and `..`, and
// existing files also by identity (hard links).
void check_distinct_files(const std::vector<std::pair<std::string, std::string>>& files) {
  namespace fs = std::filesystem;
  auto same = [](const std::string& a, const std::string& b) {
    std::error_code e1, e2, e3;
    if (fs::weakly_canonical(a, e1) == fs::weakly_canonical(b, e2) && !e1 && !e2) return true;
    return fs::exists(a, e1) && fs::exists(b, e2) && fs::equivalent(a, b, e3) && !e3;
  };
  for (size_t i = 1; i < files.size(); ++i) {
    if (files[i].second.empty()) continue;
    for (size_t k = 0; k < i; ++k)
      if (!files[k].second.empty() && same(files[i].second, files[k].second))
        throw std::runtime_error(files[i].first + ": '" + files[i].second + "' is " +
                                 (k == 0 ? "the " + files[0].first + " itself" : "also " + files[k].first) +
                                 "; not overwritten");
  }
}

int cmd_run(const std::string& scene_path, const std::string& backend_name_arg, std::vector<std::string> sets,
            const std::string& metrics_csv, const std::string& summary_json, bool quiet, const ExportArgs& ex,
            const FrameArgs& fa) {
  if (fa.dir.empty() && (!fa.size.empty() || fa.every > 0))
    throw std::runtime_error("--size and --frames-every need --frames-dir DIR");
  add_frame_overrides(fa, sets);
  const Scene scene = load_scene(scene_path, sets);
  const std::set<std::string> export_fields = parse_export_fields(ex.fields);
  if (ex.path.empty() && !ex.fields.empty()) throw std::runtime_error("--export-fields needs --export FILE");
  check_distinct_files({{"scene file", scene_path}, {"--export", ex.path}, {"--metrics-csv", metrics_csv},
                        {"--summary-json", summary_json}, {"--frames-dir", fa.dir},
                        {"the export's XDMF sidecar", ex.path.empty() || xdmf_path(ex.path) == ex.path
                                                          ? std::string()  // refused by FrameWriter, by name
                                                          : xdmf_path(ex.path)}});
  // Outputs are opened before the run, so an unwritable path fails in a
  // second, not after the simulation.
  std::ofstream csv, summary;
  if (!metrics_csv.empty()) {
    csv = open_output("--metrics-csv", metrics_csv);
    csv << "time_s,steps,fluid_particles,front_m,kinetic_energy_J,max_speed_m_s\n" << std::setprecision(9);
  }
  if (!summary_json.empty()) summary = open_output("--summary-json", summary_json);
  const Backend b = choose_backend(backend_name_arg, std::cout);
  const bool exporting = !ex.path.empty(), export_field = exporting && export_fields.count("field") > 0;
  const bool rendering = !fa.dir.empty();
  const StageNeeds needs = needs_of(scene, export_field || rendering, exporting && export_fields.count("presence") > 0);
  auto solver = make_solver(scene, b, needs);
  auto field = make_field(scene, b, needs);
  std::unique_ptr<FrameRenderer> frames;
  if (rendering) frames = std::make_unique<FrameRenderer>(scene, b, field->setup(), fa.dir);
  std::unique_ptr<FrameWriter> writer;
  if (exporting) {  // created before the run: an unwritable path fails before any step
    FileHeader h;
    h.scene_json = scene.json.dump(2);
    h.version = sphray_version();
    h.backend = backend_name(b);
    for (const Vec3f& q : solver->boundary_positions()) h.boundary.insert(h.boundary.end(), {q.x, q.y, q.z});
    try {
      writer = std::make_unique<FrameWriter>(ex.path, h, scene.export_.gzip);
    } catch (const FrameFileError& e) {
      throw std::runtime_error(std::string("--export: ") + e.what());
    }
  }
  const SceneSize size = measure_scene(scene);
  const SphParams prm = make_params(scene);
  std::cout << "scene " << scene.name << " (" << scene_path << "): " << solver->num_fluid() << " fluid particles, "
            << size.boundary << " wall particles, grid " << size.grid.nx << "x" << size.grid.ny << "x" << size.grid.nz
            << ", c0 = " << prm.speed_of_sound << " m/s, to t = " << scene.run.end_time << " s\n";
  if (const double c_auto = auto_speed_of_sound(scene), v = expected_flow_speed(scene);
      scene.sph.speed_of_sound > 0 && scene.sph.speed_of_sound < c_auto)
    std::cout << std::setprecision(3) << "  note: sph.speed_of_sound is below the automatic " << c_auto
              << " m/s (10x the flow speed " << v << " m/s the scene can reach): density varies as (v / c0)^2, about "
              << 100 * (v / scene.sph.speed_of_sound) * (v / scene.sph.speed_of_sound)
              << "% here, and the run stops if a particle outruns c0\n" << std::setprecision(6);
  if (const int layers = auto_boundary_layers(scene), given = scene.sph.boundary_layers; given > 0 && given < layers)
    std::cout << "  note: sph.boundary_layers = " << given << " is thinner than the kernel support (" << layers
              << " layers, \"auto\"): near a wall part of a particle's kernel is empty and the walls may not hold "
              << "the liquid (the summary counts the particle-steps put back on a wall face)\n";

  const double mass = prm.particle_mass;
  RunOptions opt;
  opt.progress = !quiet;
  opt.field = field.get();
  opt.field_kind = parse_field_kind(scene.field.builder);
  const int frames_every = scene.render.frames_every;
  if (!scene.field.given)  // the field is built only for the frames that use it
    opt.field_at = [&](int frame) {
      return (rendering && frame % frames_every == 0) || (export_field && frame % ex.every == 0);
    };
  const bool export_presence = exporting && export_fields.count("presence") > 0;
  if (needs.presence == PresenceMode::AtUntil)  // presence only on the frames that use it
    opt.presence_at = [&](int frame) {
      const bool field_now = !opt.field_at || opt.field_at(frame);
      return (opt.field_kind == FieldKind::Presence && field_now) || (export_presence && frame % ex.every == 0);
    };
  opt.on_output = [&](const Solver& s, int frame) {
    if (frames && frame % frames_every == 0) frames->write_frame(s.view(), *field, frame);
    if (csv.is_open()) {
      const HostParticles p = s.download();
      errno = 0;
      csv << s.time() << "," << s.steps() << "," << s.num_fluid() << ","
          << surge_front(p, scene.tank.min.x, scene.sph.spacing) << "," << kinetic_energy(p, mass) << ","
          << s.last_limits().max_speed << "\n" << std::flush;
      // Flushed per row: a run followed live (tail -f) or killed leaves whole
      // rows, and a write error (a full disk) stops the run here rather than
      // end with a cut-off CSV and exit 0.
      if (!csv) throw OutputError(write_failure("--metrics-csv", metrics_csv));
    }
    if (writer && frame % ex.every == 0) writer->submit(capture_frame(s, prm, export_fields, field.get()));
  };
  RunSummary r;
  try {
    r = run_scene(scene, *solver, opt, std::cout);
  } catch (const std::exception& e) {
    // A run stopped by a guard (or a failed write) still leaves a summary
    // that says so, where the file opened before the run was left empty.
    if (summary.is_open())
      summary << nlohmann::json{{"status", "stopped"}, {"error", e.what()}, {"scene", scene_path},
                                {"backend", backend_name(b)}, {"steps", solver->steps()},
                                {"sim_time_s", solver->time()}, {"spacing_m", scene.sph.spacing}}
                     .dump(2)
              << "\n";
    throw;  // the error being reported; a summary that could not be written is not checked
  }
  if (frames) frames->finish();  // the last PNGs are still being written
  if (csv.is_open()) {
    errno = 0;
    csv.close();
    if (!csv) throw OutputError(write_failure("--metrics-csv", metrics_csv));
  }
  print_summary(r, std::cout);
  if (frames)
    std::cout << "  frames         " << frames->frames_written() << " PNGs (" << scene.render.width << "x"
              << scene.render.height << ", " << scene.render.interfaces << " interfaces) to " << fa.dir << ", "
              << frames->mean_render_ms() << " ms per render\n";
  if (writer) {
    writer->finish();
    std::cout << "  export         " << writer->frames_written() << " frames to " << ex.path << " (XDMF sidecar for ParaView"
              << " next to it); the run waited " << writer->seconds_waited() << " s on the writer\n";
  }
  if (!summary_json.empty()) {
    nlohmann::json j = {{"status", "completed"},       {"scene", scene_path},
                        {"backend", backend_name(r.backend)}, {"steps", r.steps},
                        {"sim_time_s", r.sim_time},        {"wall_s", r.wall_seconds},
                        {"fluid_start", r.fluid_start},    {"fluid_end", r.fluid_end},
                        {"removed", r.removed},            {"clamped", r.clamped},
                        {"particle_steps", r.particle_steps}, {"spacing_m", scene.sph.spacing},
                        {"mean_dt_s", r.mean_dt},          {"max_speed_m_s", r.max_speed}};
    if (r.field_builds)
      j["field"] = {{"builder", r.field_builder}, {"volume", r.field_dims}, {"builds", r.field_builds},
                    {"ms_per_build", r.field_ms_mean}, {"builds_without_presence", r.field_without_presence}};
    write_json(summary, j, "--summary-json", summary_json);
  }
  return 0;
}

int cmd_inspect(const std::string& path) {
  const FrameReader r(path);
  std::string name = "?";
  try {
    name = nlohmann::json::parse(r.header().scene_json).value("name", "?");
  } catch (...) {
  }
  std::cout << path << ": sphray frames, format_version " << r.format_version() << ", written by sphray "
            << r.header().version << " (" << r.header().backend << " backend), scene \"" << name << "\"\n"
            << "  boundary particles " << r.header().boundary.size() / 3 << ", frames " << r.frames().size() << "\n";
  // [lo, hi] of the finite values; non-finite ones counted after it.
  auto range = [](const std::vector<float>& v, size_t stride, size_t c) {
    float lo = 0, hi = 0;
    size_t finite = 0, other = 0;
    for (size_t k = c; k < v.size(); k += stride) {
      if (!std::isfinite(v[k])) {
        ++other;
        continue;
      }
      lo = finite == 0 ? v[k] : std::min(lo, v[k]);
      hi = finite == 0 ? v[k] : std::max(hi, v[k]);
      ++finite;
    }
    std::ostringstream os;
    if (finite) os << "[" << lo << ", " << hi << "]";
    else os << "(no finite value)";
    if (other) os << " (" << other << " non-finite)";
    return os.str();
  };
  for (size_t k = 0; k < r.frames().size(); ++k) {
    const FrameInfo& fi = r.frames()[k];
    const Frame f = r.read(k);
    std::cout << "  " << fi.name << "  t = " << fi.time << " s  step " << fi.step << "  " << fi.particles
              << " particles";
    if (fi.particles)  // none left (an open top): no ranges to print
      std::cout << "  x " << range(f.position, 3, 0) << " y " << range(f.position, 3, 1) << " z "
                << range(f.position, 3, 2);
    if (!f.density.empty()) std::cout << "  density " << range(f.density, 1, 0);
    if (!f.pressure.empty()) std::cout << "  pressure " << range(f.pressure, 1, 0);
    if (!f.velocity.empty()) {
      float vmax = 0;
      size_t other = 0;
      for (size_t i = 0; i + 2 < f.velocity.size(); i += 3) {
        const float v = std::sqrt(f.velocity[i] * f.velocity[i] + f.velocity[i + 1] * f.velocity[i + 1] +
                                  f.velocity[i + 2] * f.velocity[i + 2]);
        if (std::isfinite(v)) vmax = std::max(vmax, v);
        else ++other;
      }
      std::cout << "  |v| max " << vmax;
      if (other) std::cout << " (" << other << " non-finite)";
    }
    if (!f.presence.empty()) std::cout << "  presence " << range(f.presence, 1, 0);
    if (!f.field.empty())
      std::cout << "  field " << f.field_dims[0] << "x" << f.field_dims[1] << "x" << f.field_dims[2] << " "
                << range(f.field, 1, 0) << " iso " << f.field_iso;
    std::cout << "\n";
  }
  return 0;
}

bool is_png_path(const std::string& p) {
  return p.size() > 4 && (p.compare(p.size() - 4, 4, ".png") == 0 || p.compare(p.size() - 4, 4, ".PNG") == 0);
}

// sphray writes PNG only: an image name of another format would have become a
// directory of PNGs (--out) or PNG bytes under a .jpg name (--screenshot).
// `or_else`: what else the option accepts, for the message.
void check_not_other_image(const std::string& path, const char* flag, const char* or_else = "") {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  for (const char* other : {".jpg", ".jpeg", ".bmp", ".tga", ".gif", ".tif", ".tiff", ".exr", ".hdr", ".ppm", ".webp"})
    if (ext == other)
      throw std::runtime_error(std::string(flag) + " '" + path + "': sphray writes PNG images; give a .png name" +
                               or_else);
}

// A file we are about to write after a long computation: fail now if we cannot.
void check_writable(const std::string& path, const char* flag = "--out") {
  const bool existed = std::filesystem::exists(path);
  errno = 0;
  std::FILE* f = std::fopen(path.c_str(), "ab");
  if (!f) throw std::runtime_error(write_failure(flag, path));
  std::fclose(f);
  if (!existed) std::remove(path.c_str());
}

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
  const Backend b = choose_backend(backend_arg, std::cout);
  const StageNeeds needs = needs_of(scene, true, false);
  auto solver = make_solver(scene, b, needs);
  auto field = make_field(scene, b, needs);
  FrameRenderer frames(scene, b, field->setup(), single ? "" : ra.out, "--out");
  const int last = scene.run.end_time > 0 ? 1 : 0;
  const int every = scene.render.frames_every;
  RunOptions opt;
  opt.field = field.get();
  opt.field_kind = parse_field_kind(scene.field.builder);
  opt.field_at = [&](int f) { return single ? f == last : f % every == 0; };
  opt.on_output = [&](const Solver& s, int f) {
    if (!opt.field_at(f)) return;
    if (single) frames.render_to(s.view(), *field, ra.out);
    else frames.write_frame(s.view(), *field, f);
  };
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
  const FieldSetup fs = make_field_setup(scene);
  auto field = make_field_builder(b, fs);
  FrameRenderer frames(scene, b, fs, single ? "" : ra.out, "--out");
  const FieldKind kind = parse_field_kind(scene.field.builder);
  const size_t first = ra.frame >= 0 ? size_t(ra.frame) : 0, end = ra.frame >= 0 ? first + 1 : n;
  for (size_t k = first; k < end; ++k) {
    const Frame f = reader.read(k);
    SolverInput in = make_solver_input(scene, PresenceMode::Off);
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
    field->build(solver->view(), kind);
    if (single) frames.render_to(solver->view(), *field, ra.out);
    else frames.write_frame(solver->view(), *field, int(k));
    std::cout << "  frame " << k << " (t = " << f.time << " s, " << f.count() << " particles): field "
              << field->last_ms() << " ms\n";
  }
  frames.finish();
  std::cout << "rendered " << frames.frames_written() << " frame" << (frames.frames_written() == 1 ? "" : "s")
            << " of " << ra.from << " to " << ra.out << ", " << frames.mean_render_ms() << " ms per render\n";
  return 0;
}

// CLI11 answers a mistyped command ("sphray rnu x.json", "sphray bench simm")
// with "A subcommand is required". Names the word it did not know and the
// commands there are; empty when the command words are all known.
std::string unknown_command(CLI::App& app, int argc, char** argv) {
  CLI::App* level = &app;
  for (int i = 1; i < argc; ++i) {
    const std::string word = argv[i];
    const std::vector<CLI::App*> subs = level->get_subcommands([](CLI::App*) { return true; });
    if (word.empty() || word[0] == '-' || subs.empty()) return "";  // options, or a command's own arguments
    CLI::App* next = nullptr;
    std::string names;
    for (CLI::App* s : subs) {
      names += (names.empty() ? "" : ", ") + s->get_name();
      if (s->check_name(word)) next = s;
    }
    if (!next)
      return "unknown command '" + word + "'" + (level == &app ? "" : " after '" + level->get_name() + "'") +
             ": one of " + names;
    level = next;
  }
  return "";
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"sphray: SPH liquids on the GPU, rendered as refracting metaballs"};
  app.require_subcommand(1);

  std::string scene_path, backend = "auto", metrics_csv, summary_json;
  std::vector<std::string> sets;
  bool quiet = false;
  auto* run = app.add_subcommand("run", "simulate a scene");
  run->add_option("scene", scene_path, "scene JSON file")->required();
  run->add_option("--backend", backend, "auto | cpu | cuda (auto: CUDA when a device is present)");
  run->add_option("--set", sets, "override a scene value by its dotted path, e.g. --set sph.spacing=0.02");
  run->add_option("--metrics-csv", metrics_csv, "write time, surge front, kinetic energy per output interval");
  run->add_option("--summary-json", summary_json, "write the run summary as JSON");
  run->add_flag("--quiet", quiet, "no progress lines");
  ExportArgs export_args;
  run->add_option("--export", export_args.path, "write frames to this HDF5 file (docs/formats.md)");
  run->add_option("--export-every", export_args.every, "export every K-th output frame (default 1)")
      ->check(CLI::Range(1, 1000000));
  run->add_option("--export-fields", export_args.fields,
                  "comma-separated: velocity,density,pressure,presence,field (position is always written)");
  FrameArgs frame_args;
  run->add_option("--frames-dir", frame_args.dir, "render PNG frames into this directory (docs/rendering.md)");
  run->add_option("--frames-every", frame_args.every, "a PNG every K-th output frame (default: render.frames_every)")
      ->check(CLI::Range(1, 1000000));
  run->add_option("--size", frame_args.size, "PNG size WIDTHxHEIGHT (default: render.width x render.height)");

  auto* render = app.add_subcommand("render", "render one frame or a sequence to PNG, from a scene or an HDF5 export");
  RenderArgs render_args;
  FrameArgs render_frame_args;
  render->add_option("scene", render_args.scene, "scene JSON file, or an HDF5 export (as --from FILE)");
  render->add_option("--from", render_args.from, "an HDF5 file written by sphray run --export");
  render->add_option("--out", render_args.out, "x.png: one image; otherwise a directory for frame_NNNNNN.png")
      ->required();
  render->add_option("--time", render_args.time, "scene: simulate to this time and render it (default run.end_time)")
      ->check(CLI::Range(0.0, 1e6));
  render->add_option("--frame", render_args.frame, "--from: render this frame only (default: all)")
      ->check(CLI::Range(0, 100000000));
  render->add_option("--backend", backend, "auto | cpu | cuda");
  render->add_option("--set", sets, "override a scene value, e.g. --set render.interfaces=8");
  render->add_option("--size", render_frame_args.size, "image size WIDTHxHEIGHT");
  render->add_option("--frames-every", render_frame_args.every, "a directory --out: every K-th output frame")
      ->check(CLI::Range(1, 1000000));

  auto* view = app.add_subcommand("view", "the real-time dam break in a window (GLFW + OpenGL, Dear ImGui panel)");
  ViewOptions view_opt;
  FrameArgs view_frame_args;
  view->add_option("scene", view_opt.scene, "scene JSON file (default: a built-in small dam break)");
  view->add_option("--backend", view_opt.backend, "auto | cpu | cuda");
  view->add_option("--set", view_opt.sets, "override a scene value, e.g. --set render.interfaces=8");
  view->add_option("--size", view_frame_args.size, "raycast image (and window) size WIDTHxHEIGHT");
  view->add_option("--substeps", view_opt.substeps, "SPH steps per frame (changeable in the panel)")
      ->check(CLI::Range(1, 20));
  view->add_option("--frames", view_opt.frames, "run this many frames, then exit")->check(CLI::Range(1, 1000000));
  view->add_option("--screenshot", view_opt.screenshot, "with --frames: write the window's last frame as PNG");
  std::string view_resize;
  view->add_option("--resize", view_resize, "after the first frame, resize the window to WIDTHxHEIGHT (the image follows)");

  auto* inspect = app.add_subcommand("inspect", "summary of an HDF5 frames file: frames, times, counts, value ranges");
  std::string inspect_path;
  inspect->add_option("file", inspect_path, "a file written by sphray run --export")->required();

  auto* bench = app.add_subcommand("bench", "benchmarks");
  bench->require_subcommand(1);
  auto* bsim = bench->add_subcommand("sim", "ms per SPH step by stage, with and without presence");
  std::string bench_scene, sizes_text, json_out;
  BenchSimOptions bopt;
  bsim->add_option("--scene", bench_scene,
                   "dam-break scene whose spacing is scaled to each size (default: scenes/bench/dam_break.json, "
                   "built in)");
  bsim->add_option("--backend", backend, "auto | cpu | cuda");
  bsim->add_option("--sizes", sizes_text, "fluid particle counts (default 125k,1M,4M on CUDA, 8k,27k on CPU)");
  bsim->add_option("--warmup", bopt.warmup, "warm-up steps")->check(CLI::Range(0, 100000));
  bsim->add_option("--steps", bopt.steps, "measured steps")->check(CLI::Range(1, 100000));
  bsim->add_option("--json", json_out, "write results as JSON");
  bsim->add_option("--set", bopt.overrides, "override a scene value for every size, e.g. --set sph.smoothing_ratio=1.3");

  auto* bfield = bench->add_subcommand("field", "naive vs presence vs gather density-field builders on a collapsed dam break");
  std::string field_sizes_text, field_json_out;
  BenchFieldOptions fopt;
  bfield->add_option("--backend", backend, "auto | cpu | cuda");
  bfield->add_option("--sizes", field_sizes_text,
                     "fluid particle counts (default 8k,27k,64k,125k,1M,4M on CUDA, 8k,27k on CPU)");
  bfield->add_option("--volume", fopt.volume, "volume edge in voxels (default 64 up to 200k particles, else 256)")
      ->check(CLI::Range(8, 1024));
  bfield->add_option("--warmup", fopt.warmup, "warm-up builds per builder")->check(CLI::Range(0, 10000));
  bfield->add_option("--frames", fopt.frames, "measured builds per builder")->check(CLI::Range(1, 100000));
  bfield->add_option("--collapse", fopt.collapse, "build at T = t sqrt(2g/a) (column collapsed)")
      ->check(CLI::Range(0.0, 100.0));
  bfield->add_option("--json", field_json_out, "write results as JSON");
  bfield->add_option("--set", fopt.overrides, "override a value of the generated scene, e.g. --set field.clip=2");

  auto* bframe = bench->add_subcommand("frame", "whole frames: SPH substeps + field + raycast, per-stage medians");
  std::string frame_sizes_text, frame_json_out;
  BenchFrameOptions bfo;
  bframe->add_option("--backend", backend, "auto | cpu | cuda");
  bframe->add_option("--sizes", frame_sizes_text, "fluid particle counts (default 125k,1M on CUDA, 8k on CPU)");
  bframe->add_option("--width", bfo.width, "image width")->check(CLI::Range(16, 8192));
  bframe->add_option("--height", bfo.height, "image height")->check(CLI::Range(16, 8192));
  bframe->add_option("--interfaces", bfo.interfaces, "interfaces per ray")->check(CLI::Range(1, 8));
  bframe->add_option("--substeps", bfo.substeps, "SPH steps per frame")->check(CLI::Range(1, 1000));
  bframe->add_option("--builder", bfo.builder, "naive | presence | gather");
  bframe->add_option("--warmup", bfo.warmup, "warm-up frames")->check(CLI::Range(0, 10000));
  bframe->add_option("--frames", bfo.frames, "measured frames")->check(CLI::Range(1, 100000));
  bframe->add_option("--collapse", bfo.collapse, "start at T = t sqrt(2g/a)")->check(CLI::Range(0.0, 100.0));
  bframe->add_option("--png-dir", bfo.png_dir, "write each size's last frame here");
  bframe->add_option("--json", frame_json_out, "write results as JSON");
  bframe->add_option("--set", bfo.overrides, "override a value of the generated scene, e.g. --set render.step=0.25");

  auto* brender = bench->add_subcommand("render", "raycast image error (PSNR vs a fine reference) against render time");
  std::string render_json_out, render_size_text;
  BenchRenderOptions bro;
  brender->add_option("--backend", backend, "auto | cpu | cuda");
  brender->add_option("--size", render_size_text, "fluid particle count (default 125k on CUDA, 8k on CPU)");
  brender->add_option("--width", bro.width, "image width")->check(CLI::Range(16, 8192));
  brender->add_option("--height", bro.height, "image height")->check(CLI::Range(16, 8192));
  brender->add_option("--reference-step", bro.reference_step, "reference march step [voxels]")
      ->check(CLI::Range(0.001, 0.5));
  brender->add_option("--warmup", bro.warmup, "warm-up renders")->check(CLI::Range(0, 10000));
  brender->add_option("--frames", bro.frames, "measured renders")->check(CLI::Range(1, 100000));
  brender->add_option("--png-dir", bro.png_dir, "write the reference and the default-setting image here");
  brender->add_option("--json", render_json_out, "write results as JSON");
  brender->add_option("--set", bro.overrides, "override a value of the generated scene");

  // CLI11's own errors (an option's range, a missing value) in sphray's form.
  app.failure_message([](const CLI::App* a, const CLI::Error& e) {
    return "sphray: error: " + CLI::FailureMessage::simple(a, e);
  });
  if (const std::string unknown = unknown_command(app, argc, argv); !unknown.empty()) {
    std::fprintf(stderr, "sphray: error: %s\n", unknown.c_str());
    return 2;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? 0 : 2;
  }

  try {
    if (run->parsed())
      return cmd_run(scene_path, backend, sets, metrics_csv, summary_json, quiet, export_args, frame_args);
    if (view->parsed()) {
      if (!view_opt.screenshot.empty() && view_opt.frames == 0)
        throw std::runtime_error("--screenshot needs --frames N");
      if (!view_opt.screenshot.empty()) {
        check_not_other_image(view_opt.screenshot, "--screenshot");
        check_writable(view_opt.screenshot, "--screenshot");
      }
      add_frame_overrides(view_frame_args, view_opt.sets);
      if (!view_resize.empty()) {
        std::tie(view_opt.resize_w, view_opt.resize_h) = parse_wxh(view_resize, "--resize");
        if (view_opt.resize_w < 16 || view_opt.resize_h < 16 || view_opt.resize_w > 8192 || view_opt.resize_h > 8192)
          throw std::runtime_error("--resize '" + view_resize + "': each side must be 16 to 8192 pixels");
      }
      return run_viewer(view_opt, std::cout);
    }
    if (render->parsed()) {
      if (!render_args.scene.empty() && render_args.from.empty()) {  // an export given where a scene goes
        std::ifstream f(render_args.scene, std::ios::binary);
        std::string head(8, '\0');
        if (f.read(&head[0], 8) && is_hdf5_signature(head)) std::swap(render_args.scene, render_args.from);
      }
      if (render_args.scene.empty() == render_args.from.empty())
        throw std::runtime_error("render: give either a scene file or --from FILE.h5");
      if (!render_args.from.empty() && render_args.time >= 0) throw std::runtime_error("--time applies to a scene, not --from");
      if (render_args.from.empty() && render_args.frame >= 0) throw std::runtime_error("--frame applies to --from FILE");
      add_frame_overrides(render_frame_args, sets);
      return render_args.from.empty() ? render_scene(render_args, backend, sets) : render_file(render_args, backend, sets);
    }
    if (bframe->parsed() || brender->parsed()) {
      const std::string& jpath = bframe->parsed() ? frame_json_out : render_json_out;
      std::ofstream jf;
      if (!jpath.empty()) jf = open_output("--json", jpath);
      const Backend b = choose_backend(backend, std::cout);
      nlohmann::json j;
      if (bframe->parsed()) {
        bfo.sizes = parse_sizes(!frame_sizes_text.empty() ? frame_sizes_text : b == Backend::Cuda ? "125k,1M" : "8k");
        parse_field_kind(bfo.builder);  // a bad name fails before the simulation
        const auto rows = bench_frame(b, bfo, std::cout);
        print_table(rows, std::cout);
        j = to_json(rows, b, bfo);
      } else {
        const auto sizes = parse_sizes(!render_size_text.empty() ? render_size_text : b == Backend::Cuda ? "125k" : "8k");
        if (sizes.size() != 1) throw std::runtime_error("--size: one particle count");
        bro.particles = sizes[0];
        const auto rows = bench_render(b, bro, std::cout);
        print_table(rows, std::cout);
        j = to_json(rows, b, bro);
      }
      if (jf.is_open()) write_json(jf, j, "--json", jpath);
      return 0;
    }
    if (inspect->parsed()) return cmd_inspect(inspect_path);
    if (bfield->parsed()) {
      std::ofstream jf;
      if (!field_json_out.empty()) jf = open_output("--json", field_json_out);
      const Backend b = choose_backend(backend, std::cout);
      fopt.sizes = parse_sizes(!field_sizes_text.empty() ? field_sizes_text
                               : b == Backend::Cuda   ? "8k,27k,64k,125k,1M,4M"
                                                      : "8k,27k");
      const auto rows = bench_field(b, fopt, std::cout);
      print_table(rows, std::cout);
      if (jf.is_open()) write_json(jf, to_json(rows, b, fopt), "--json", field_json_out);
      return 0;
    }
    if (bsim->parsed()) {
      std::ofstream jf;
      if (!json_out.empty()) jf = open_output("--json", json_out);
      const Backend b = choose_backend(backend, std::cout);
      bopt.sizes = parse_sizes(!sizes_text.empty() ? sizes_text : b == Backend::Cuda ? "125k,1M,4M" : "8k,27k");
      // The default scene is compiled in, so that the benchmark runs from any directory.
      const auto rows = bench_scene.empty()
                            ? bench_sim(builtin::bench_dam_break, "scenes/bench/dam_break.json (built in)", b, bopt,
                                        std::cout)
                            : bench_sim(read_scene_text(bench_scene), bench_scene, b, bopt, std::cout);
      print_table(rows, std::cout);
      if (jf.is_open()) write_json(jf, to_json(rows, b, bopt), "--json", json_out);
      return 0;
    }
  } catch (const FrameFileError& e) {
    std::fprintf(stderr, "sphray: error: %s\n", e.what());
    return run->parsed() ? 1 : 2;  // a failed write during a run; a bad file given to read (run, render --from)
  } catch (const OutputError& e) {  // PNG, CSV or JSON not written after the run began (a full disk)
    std::fprintf(stderr, "sphray: error: %s\n", e.what());
    return 1;
  } catch (const SceneError& e) {
    std::fprintf(stderr, "sphray: error: %s\n", e.what());
    return 2;
  } catch (const SimulationError& e) {
    std::fprintf(stderr, "sphray: simulation stopped: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sphray: error: %s\n", e.what());
    return 2;
  }
  return 0;
}
