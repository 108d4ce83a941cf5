// `sphray run SCENE`: simulates a scene, with the outputs its flags ask for
// (metrics CSV, summary JSON, HDF5 export, PNG frames).
#include <cerrno>
#include <cmath>
#include <cstring>
#include <iomanip>
#include <iostream>
#include <optional>
#include <set>
#include <sstream>

#include "cli.h"
#include "commands.h"
#include "ranks.h"
#include "dist/slab_solver.h"
#include "io/export.h"
#include "io/frames_h5.h"
#include "pipeline/pipeline.h"
#include "pipeline/setup.h"
#include "sph/skin.h"
#include "pipeline/sinks.h"

namespace sphray::cli {

namespace {

struct ExportArgs {
  std::string path;
  int every = 1;
  std::string fields;
};

struct RunArgs {
  std::string scene_path, backend = "auto", metrics_csv, summary_json, resume;
  std::vector<std::string> sets;
  bool quiet = false;
  int rebalance_every = SlabOptions{}.rebalance_every;
  std::string overlap = "auto";
  std::string cut_axis = "auto";
  ExportArgs ex;
  FrameArgs fa;
};

// The export's file header: the scene, the build, the walls.
FileHeader export_header(const Scene& scene, Backend b, const Solver& solver) {
  FileHeader h;
  h.scene_json = scene.json.dump(2);
  h.version = sphray_version();
  h.backend = backend_name(b);
  for (const Vec3f& q : solver.boundary_positions()) h.boundary.insert(h.boundary.end(), {q.x, q.y, q.z});
  return h;
}

// The start line, and notes on settings that weaken the run.
void print_start(const ResolvedScene& rs, const std::string& scene_path, const Solver& solver) {
  const Scene& scene = rs.scene;
  const SceneSize& size = rs.size;
  const SphParams& prm = rs.params;
  std::cout << "scene " << scene.name << " (" << scene_path << "): " << solver_name(solver.kind()) << ", "
            << solver.num_fluid() << " fluid particles, " << solver.boundary_positions().size() << " wall particles, grid "
            << size.grid.nx << "x" << size.grid.ny << "x" << size.grid.nz;
  if (!scene.obstacles.empty()) {
    size_t tris = 0;
    for (const Obstacle& o : scene.obstacles) tris += o.mesh.size();
    std::cout << ", " << scene.obstacles.size() << " obstacle(s) of " << tris << " triangles";
    if (const SkinSet* skins = solver.skins()) {
      for (size_t k = 0; k < skins->size(); ++k) {
        const SkinGeometry& g = skins->geometry(k);
        std::cout << " (obstacle " << g.input.obstacle << ": a skin of " << g.map.size() << " texels, "
                  << g.map.mean_spacing * 1e3 << " mm apart"
                  << (g.map.embedding.iterations ? ", mapped to the sphere after " +
                                                        std::to_string(g.map.embedding.iterations) + " flow steps"
                                                  : std::string())
                  << ")";
      }
    }
  }
  // PBF's and DFSPH's tank walls are its planes; the wall particles counted above are the obstacles'.
  const char* walls = scene.obstacles.empty() ? "the tank's planes" : "the tank's planes and the obstacles' wall particles";
  if (solver.kind() == SolverKind::Pbf)
    std::cout << ", " << scene.sph.pbf.iterations << " iterations, walls: " << walls;
  else if (solver.kind() == SolverKind::Dfsph)
    std::cout << ", tolerance " << 100 * scene.sph.dfsph.tolerance << "% (divergence "
              << 100 * scene.sph.dfsph.divergence_tolerance << "%), viscosity " << rs.dfsph.viscosity / 10
              << " m^2/s, walls: " << walls;
  else
    std::cout << ", c0 = " << prm.speed_of_sound << " m/s";
  std::cout << ", to t = " << scene.run.end_time << " s\n";
  if (const double c_auto = auto_speed_of_sound(scene), v = expected_flow_speed(scene);
      scene.sph.speed_of_sound > 0 && scene.sph.speed_of_sound < c_auto)
    std::cout << std::setprecision(3) << "  note: sph.speed_of_sound is below the automatic " << c_auto
              << " m/s (10x the flow speed " << v << " m/s the scene can reach): density varies as (v / c0)^2, about "
              << 100 * (v / scene.sph.speed_of_sound) * (v / scene.sph.speed_of_sound)
              << "% here, and the run stops if a particle outruns c0\n" << std::setprecision(6);
  if (const std::string note = cpu_scale_note(rs, solver.backend()); !note.empty()) std::cout << "  note: " << note << "\n";
  // DFSPH's explicit viscosity bounds its step (dfsph_params.h); a large
  // dfsph.viscosity makes that bound, not the flow, set the run's length.
  if (solver.kind() == SolverKind::Dfsph) {
    const double cfl_dt = std::min(scene.run.max_dt, scene.sph.cfl * scene.sph.spacing / double(rs.dfsph.speed_floor));
    if (double(rs.dfsph.max_dt_viscous) < 0.25 * cfl_dt)
      std::cout << std::setprecision(3) << "  note: dfsph.viscosity = " << rs.dfsph.viscosity / 10
                << " m^2/s limits the step to " << rs.dfsph.max_dt_viscous << " s (the explicit viscous force's "
                << "stability), " << cfl_dt / double(rs.dfsph.max_dt_viscous) << "x below the flow's "
                << cfl_dt << " s: about " << scene.run.end_time / double(rs.dfsph.max_dt_viscous)
                << " steps to t = " << scene.run.end_time << " s\n" << std::setprecision(6);
  }
  if (const int layers = scene.sph.auto_boundary_layers(), given = scene.sph.boundary_layers; given > 0 && given < layers)
    std::cout << "  note: sph.boundary_layers = " << given << " is thinner than the kernel support (" << layers
              << " layers, \"auto\"): near a wall part of a particle's kernel is empty and the walls may not hold "
              << "the liquid (the summary counts the particle-steps put back on a wall face)\n";
}

nlohmann::json completed_json(const RunSummary& r, const RunArgs& a, const Scene& scene) {
  nlohmann::json j = {{"status", "completed"},       {"scene", a.scene_path},
                      {"backend", backend_name(r.backend)}, {"steps", r.steps},
                      {"sim_time_s", r.sim_time},        {"wall_s", r.wall_seconds},
                      {"fluid_start", r.fluid_start},    {"fluid_end", r.fluid_end},
                      {"removed", r.removed},            {"clamped", r.clamped},
                      {"particle_steps", r.particle_steps}, {"spacing_m", scene.sph.spacing},
                      {"mean_dt_s", r.mean_dt},          {"max_speed_m_s", r.max_speed},
                      {"realtime_factor", r.realtime_factor()}, {"solver", r.solver}};
  j["max_speed_time_s"] = r.max_speed_time;
  // The steps that each limit held (docs/formats.md).
  for (int b = 0; b < kStepBounds; ++b) j["step_bounds"][step_bound_key(b)] = r.bound_steps[b];
  if (r.max_speed_id != kNoBadParticle) {  // one rank: where the largest speed was
    j["max_speed_particle"] = r.max_speed_id;
    j["max_speed_position_m"] = {r.max_speed_at.x, r.max_speed_at.y, r.max_speed_at.z};
  }
  const StageTimes& st = r.mean_stage_ms;
  j["stage_ms"] = {{"grid", st.grid}, {"pairs", st.pairs}, {"integrate", st.integrate}, {"exchange", st.exchange}};
  if (st.skin > 0) j["stage_ms"]["skin"] = st.skin;
  if (r.iterations_max > 0)
    j["constraint"] = {{"iterations_mean", r.iterations_mean}, {"iterations_max", r.iterations_max},
                       {"density_error_mean", r.density_error_mean}, {"density_error_max", r.density_error_max},
                       {"unconverged_steps", r.unconverged_steps}};
  if (r.divergence_iterations_max > 0)
    j["constraint"]["divergence_iterations"] = {{"mean", r.divergence_iterations_mean},
                                                {"max", r.divergence_iterations_max}};
  if (r.field_builds)
    j["field"] = {{"builder", r.field_builder}, {"kernel", r.field_kernel}, {"volume", r.field_dims},
                  {"builds", r.field_builds}, {"ms_per_build", r.field_ms_mean},
                  {"builds_without_presence", r.field_without_presence}};
  return j;
}

// The run's outputs. The files are opened before the run: an unwritable path
// fails in a second, not after the simulation.
struct RunOutputs {
  std::unique_ptr<MetricsSink> metrics;
  std::unique_ptr<ExportSink> exporter;
  std::unique_ptr<PngSink> png;
  std::ofstream summary;

  std::vector<OutputSink*> sinks() const {
    std::vector<OutputSink*> v;
    for (OutputSink* k : {static_cast<OutputSink*>(png.get()), static_cast<OutputSink*>(metrics.get()),
                          static_cast<OutputSink*>(exporter.get())})
      if (k) v.push_back(k);
    return v;
  }
};

void print_outputs(RunOutputs& o, const RunArgs& a, const Scene& scene) {
  if (o.png)
    std::cout << "  frames         " << o.png->frames().frames_written() << " PNGs (" << scene.render.width << "x"
              << scene.render.height << ", " << scene.render.interfaces << " interfaces) to " << a.fa.dir << ", "
              << o.png->frames().mean_render_ms() << " ms per render\n";
  if (o.exporter) {
    ExportSink& e = *o.exporter;
    e.finish();
    std::cout << "  export         " << e.frames_written() << " frames to " << a.ex.path
              << " (XDMF sidecar for ParaView next to it); "
              << (e.by_ranks() ? "every rank wrote its rows (parallel HDF5), " : "the run waited ")
              << e.seconds_in_run() << (e.by_ranks() ? " s on rank 0\n" : " s on the writer\n");
  }
}

// The output flags checked against each other, and the files they name.
void check_outputs(const RunArgs& a) {
  const ExportArgs& ex = a.ex;
  if (ex.path.empty() && !ex.fields.empty()) throw std::runtime_error("--export-fields needs --export FILE");
  check_distinct_files({{"scene file", a.scene_path}, {"--export", ex.path}, {"--resume", a.resume}, {"--metrics-csv", a.metrics_csv},
                        {"--summary-json", a.summary_json}, {"--frames-dir", a.fa.dir},
                        {"the export's XDMF sidecar", ex.path.empty() || xdmf_path(ex.path) == ex.path
                                                          ? std::string()  // refused by FrameWriter, by name
                                                          : xdmf_path(ex.path)}});
}

// A run stopped by a guard (or a failed write) still leaves a summary that
// says so, where the file opened before the run was left empty.
void write_stopped_summary(std::ofstream& summary, const std::string& error, const RunArgs& a, Backend b,
                           const Solver& solver, const Scene& scene) {
  if (!summary.is_open()) return;
  summary << nlohmann::json{{"status", "stopped"}, {"error", error}, {"scene", a.scene_path},
                            {"backend", backend_name(b)}, {"steps", solver.steps()},
                            {"sim_time_s", solver.time()}, {"spacing_m", scene.sph.spacing}}
                 .dump(2)
          << "\n";
}

// Refuses an export whose scene fills another lattice than `scene` (another
// spacing or other fluid blocks): a frame's particle ids are indices into
// the lattice of the scene that wrote it, and in this one they would name
// other particles (or look like particles that left the run).
void check_same_lattice(const std::string& path, const std::string& exported_json, const Scene& scene) {
  const std::string other = "--resume: " + path + " was exported from another scene or spacing: ";
  nlohmann::json e;
  try {
    e = nlohmann::json::parse(exported_json);
  } catch (const nlohmann::json::exception&) {
    throw std::runtime_error("--resume: " + path + ": its scene attribute is not JSON");
  }
  const nlohmann::json& mine = scene.json;
  const nlohmann::json::json_pointer at("/sph/spacing");
  const nlohmann::json spacing = e.contains(at) ? e[at] : nlohmann::json();
  if (!spacing.is_number() || spacing.get<double>() != scene.sph.spacing) {
    std::ostringstream os;
    os << other << "its sph.spacing is " << spacing.dump() << ", this scene's " << scene.sph.spacing
       << " (resume at the spacing that wrote it)";
    throw std::runtime_error(os.str());
  }
  auto boxes = [](const nlohmann::json& j) {
    std::vector<nlohmann::json> b;
    if (j.contains("fluid") && j["fluid"].is_array())
      for (const auto& f : j["fluid"]) b.push_back({f.value("min", nlohmann::json()), f.value("max", nlohmann::json())});
    return b;
  };
  if (boxes(e) != boxes(mine))
    throw std::runtime_error(other + "its fluid blocks (min, max) are not this scene's");
}

// The last frame of an export, to resume from (--resume).
Frame last_frame(const std::string& path, const Scene& scene) {
  try {
    const FrameReader reader(path);
    if (reader.frames().empty()) throw std::runtime_error("--resume: " + path + " holds no frame");
    check_same_lattice(path, reader.header().scene_json, scene);
    return reader.read(reader.frames().size() - 1);
  } catch (const FrameFileError& e) {
    throw std::runtime_error(std::string("--resume: ") + e.what());
  }
}

// Each rank's mean stage times (rank 0 receives them; the others an empty list).
std::vector<StageTimes> stage_times_by_rank(Comm& comm, const StageTimes& mine) {
  std::vector<char> bytes(sizeof(StageTimes));
  std::memcpy(bytes.data(), &mine, sizeof(StageTimes));
  std::vector<StageTimes> out;
  for (const std::vector<char>& b : comm.gather(bytes)) {
    StageTimes t;
    if (b.size() == sizeof(StageTimes)) std::memcpy(&t, b.data(), sizeof(StageTimes));
    out.push_back(t);
  }
  return out;
}

// What a run over several ranks cannot do yet, refused before it starts:
// presence (the exchange reorders the particles after the pair loop that
// sums it) and DFSPH's pressures. The presence builder then builds with full extents, as from an
// export (`sphray render --from`).
void check_several_ranks(const Scene& scene, const std::set<std::string>& fields) {
  auto refuse = [](const std::string& what) {
    throw std::runtime_error(what + " is not available in a run over several ranks (mpirun -np > 1) yet; "
                             "run it with one rank");
  };
  if (fields.count("presence")) refuse("--export-fields presence");
  if (scene.sph.presence) refuse("particle presence on every step (sph.presence)");
  // DFSPH's pressure is its solve's, which the gather does not carry (an
  // export would hold the equation of state's instead).
  if (fields.count("pressure") && scene.sph.solver == SolverKind::Dfsph) refuse("--export-fields pressure under dfsph");
}

// Whether every rank of a run over several writes its rows of the export
// (dist/rank_export.h) rather than rank 0 all of it: scene export.writer,
// "auto" where this build and the export allow it; "parallel" where they do
// not is refused.
bool ranks_write_export(const Scene& scene, const std::set<std::string>& fields) {
  const std::string& w = scene.export_.writer;
  if (w == "rank0") return false;
  const std::string why = !parallel_hdf5_built()
                              ? "this sphray was built without parallel HDF5 (Debian/Ubuntu libhdf5-openmpi-dev, "
                                "CMake SPHRAY_PARALLEL_HDF5)"
                              : rank_export_refusal(fields, scene.export_.gzip);
  if (w == "parallel" && !why.empty())
    throw std::runtime_error("export.writer \"parallel\": " + why + "; set export.writer to \"auto\" or \"rank0\"");
  return why.empty();
}

int cmd_run(RunArgs a) {
  const std::unique_ptr<Comm> comm = run_ranks();
  const bool several = comm->size() > 1, root = comm->rank() == 0;
  if (!root) std::cout.rdbuf(nullptr);  // rank 0 speaks for the run
  if (a.fa.dir.empty() && (!a.fa.size.empty() || a.fa.every > 0))
    throw std::runtime_error("--size and --frames-every need --frames-dir DIR");
  add_frame_overrides(a.fa, a.sets);
  const ResolvedScene rs = resolve_scene(load_scene(a.scene_path, a.sets));
  const Scene& scene = rs.scene;
  std::set<std::string> export_fields = parse_export_fields(a.ex.fields);
  if (export_fields.count("pressure") && scene.sph.solver == SolverKind::Pbf)
    throw std::runtime_error("--export-fields: the pbf solver has no pressure (its density constraint moves positions); "
                             "export density instead");
  if (a.overlap != "auto" && scene.sph.solver != SolverKind::Pbf)
    throw std::runtime_error(std::string("--overlap ") + a.overlap +
                             ": only PBF's ghost refresh runs beside its passes; this scene runs " +
                             solver_name(scene.sph.solver));
  check_outputs(a);
  const std::set<std::string> fields_asked = export_fields;
  // Rank 0 writes every output (a run over several ranks gathers its
  // particles there at each output frame), except an export that every rank
  // writes its rows of.
  const bool ranks_write = several && !a.ex.path.empty() && ranks_write_export(scene, fields_asked);
  RunOutputs out;
  if (!a.ex.path.empty() && (root || ranks_write))
    out.exporter = std::make_unique<ExportSink>(a.ex.every, std::move(export_fields), rs.params);
  if (root) {
    if (!a.fa.dir.empty()) out.png = std::make_unique<PngSink>(a.fa.dir, scene.render);
    if (!a.metrics_csv.empty()) out.metrics = std::make_unique<MetricsSink>(a.metrics_csv, scene, rs.params);
    if (!a.summary_json.empty()) out.summary = open_output("--summary-json", a.summary_json);
  }
  const Backend b = choose_backend(a.backend, std::cout);
  std::optional<Frame> resume;
  if (!a.resume.empty()) resume = last_frame(a.resume, scene);
  // The sinks say what they need; the stages follow from that.
  const StageNeeds needs = needs_of(scene, out.sinks());
  std::unique_ptr<Solver> solver;
  if (several) {
    check_several_ranks(scene, fields_asked);
    pick_rank_device(b);
    const SolverMaker make = b == Backend::Cuda ? SolverMaker(make_cuda_solver) : SolverMaker(make_cpu_solver);
    // Each rank's memory: an even share before the particles are made (a
    // scene too large for every rank is refused before it fills the host),
    // then its slab with ghosts; rank 0's frame view holds every particle.
    RankShare share{comm->rank(), comm->size(), (rs.size.fluid + size_t(comm->size()) - 1) / size_t(comm->size()),
                    root && (needs.field || out.png)};
    share.ranks_on_node = local_size();
    share.even = true;
    check_fits(rs, b, needs.field, &share);
    const SolverInput in = make_solver_input(rs, PresenceMode::Off, resume ? &*resume : nullptr);
    const SlabPlan plan = plan_slabs(in, comm->size(), a.cut_axis == "auto" ? -1 : a.cut_axis[0] - 'x');
    share.fluid = held_particles(in, plan, comm->rank());
    share.even = false;
    check_fits(rs, b, needs.field, &share);
    std::cout << "ranks: " << comm->size() << " slabs along " << axis_name(plan.axis) << ", cut at";
    for (double c : plan.cuts) std::cout << " " << c;
    std::cout << " m, halo " << plan.halo << " m; the most particles a rank holds with its ghosts, cut along";
    for (int ax = 0; ax < 3; ++ax) {
      std::cout << (ax ? ", " : " ") << axis_name(ax) << ": ";
      if (plan.held[ax] > 0) std::cout << size_t(std::lround(plan.held[ax]));
      else std::cout << "-";
    }
    std::cout << "\n";
    SlabOptions so;
    so.frame_view = needs.field || out.png;  // rank 0 builds the field and renders from the gathered particles
    // Alike on every rank: whether an output reads all particles on rank 0.
    so.gather_to_root = !ranks_write || !a.metrics_csv.empty() || !a.fa.dir.empty() || scene.field.every_frame;
    so.keep_owned = ranks_write;
    so.rebalance_every = a.rebalance_every;
    so.overlap_above = a.overlap == "on" ? 0.0f : a.overlap == "off" ? SlabBounds::kOverlapNever : SlabBounds::kOverlapAuto;
    solver = make_slab_solver(in, plan, *comm, b, make, so);
  } else {
    solver = make_solver(rs, b, needs, resume ? &*resume : nullptr);
  }
  auto field = root ? make_field(rs, b, needs) : nullptr;  // rank 0 builds it (from the gathered particles)
  if (out.png) out.png->open(scene, b, make_field_setup(rs));
  if (out.exporter) {  // created before the run: an unwritable path fails before any step
    try {
      if (ranks_write)
        out.exporter->open_ranks(a.ex.path, export_header(scene, b, *solver), *comm);
      else
        out.exporter->open(a.ex.path, export_header(scene, b, *solver), scene.export_.gzip);
    } catch (const FrameFileError& e) {
      throw std::runtime_error(std::string("--export: ") + e.what());
    }
  }
  print_start(rs, a.scene_path, *solver);
  if (resume)
    std::cout << "resumed from " << a.resume << " at t = " << resume->time << " s (step " << resume->step << ", "
              << resume->count() << " particles)\n";

  RunOptions opt;
  opt.progress = !a.quiet;
  opt.field = field.get();
  opt.sinks = out.sinks();
  // Alike on every rank (from the arguments and the scene, not from rank 0's sinks).
  opt.gather_frames = !a.ex.path.empty() || !a.metrics_csv.empty() || !a.fa.dir.empty() || scene.field.every_frame;
  RunSummary r;
  try {
    r = run_scene(scene, *solver, opt, std::cout);
  } catch (const std::exception& e) {
    write_stopped_summary(out.summary, e.what(), a, b, *solver, scene);
    throw;  // the error being reported; a summary that could not be written is not checked
  }
  if (out.png) out.png->frames().finish();  // the last PNGs are still being written
  if (out.metrics) out.metrics->finish();
  const std::vector<StageTimes> by_rank = several ? stage_times_by_rank(*comm, r.mean_stage_ms) : std::vector<StageTimes>{};
  print_summary(r, std::cout);
  for (size_t k = 0; k < by_rank.size(); ++k) {
    const StageTimes& t = by_rank[k];
    std::cout << (k == 0 ? "  by rank        " : "                 ") << "rank " << k << ": grid " << t.grid
              << ", pairs " << t.pairs << ", integrate " << t.integrate << ", exchange " << t.exchange << " ms per step\n";
  }
  print_outputs(out, a, scene);
  if (out.summary.is_open()) {
    nlohmann::json j = completed_json(r, a, scene);
    for (const StageTimes& t : by_rank)
      j["stage_ms_by_rank"].push_back(
          {{"grid", t.grid}, {"pairs", t.pairs}, {"integrate", t.integrate}, {"exchange", t.exchange}});
    write_json(out.summary, j, "--summary-json", a.summary_json);
  }
  return 0;
}

}  // namespace

CLI::App* add_run_command(CLI::App& app, int& exit_code) {
  auto a = std::make_shared<RunArgs>();
  auto* run = app.add_subcommand("run", "simulate a scene");
  run->add_option("scene", a->scene_path, "scene JSON file")->required();
  run->add_option("--backend", a->backend, "auto | cpu | cuda (auto: CUDA when a device is present)");
  run->add_option("--set", a->sets, "override a scene value by its dotted path, e.g. --set sph.spacing=0.02");
  run->add_option("--metrics-csv", a->metrics_csv, "write time, surge front, kinetic energy per output interval");
  run->add_option("--summary-json", a->summary_json, "write the run summary as JSON");
  run->add_flag("--quiet", a->quiet, "no progress lines");
  run->add_option("--rebalance-every", a->rebalance_every,
                  "a run over several ranks: steps between balance checks of the ranks' particle counts (the cuts "
                  "move past 10% imbalance; 0: never)")
      ->check(CLI::Range(0, 1000000));
  run->add_option("--overlap", a->overlap,
                  "a PBF run over several ranks: compute first what the peers read and send it while the rest of "
                  "each pass runs, skipping the ghosts (auto: on ranks whose ghosts are 6% or more of their "
                  "particles; on; off)")
      ->check(CLI::IsMember({"auto", "on", "off"}));
  run->add_option("--cut-axis", a->cut_axis,
                  "a run over several ranks: the axis its slabs are cut along (auto: the one whose busiest rank "
                  "holds the fewest particles with its ghosts; x; y; z)")
      ->check(CLI::IsMember({"auto", "x", "y", "z"}));
  run->add_option("--resume", a->resume,
                  "start from the last frame of this export (written with --export-fields velocity,density), on any "
                  "number of ranks");
  run->add_option("--export", a->ex.path, "write frames to this HDF5 file (docs/formats.md)");
  run->add_option("--export-every", a->ex.every, "export every K-th output frame (default 1)")
      ->check(CLI::Range(1, 1000000));
  run->add_option("--export-fields", a->ex.fields,
                  "comma-separated: velocity,density,pressure,presence,field (position is always written)");
  run->add_option("--frames-dir", a->fa.dir, "render PNG frames into this directory (docs/rendering.md)");
  run->add_option("--frames-every", a->fa.every, "a PNG every K-th output frame (default: render.frames_every)")
      ->check(CLI::Range(1, 1000000));
  run->add_option("--size", a->fa.size, "PNG size WIDTHxHEIGHT (default: render.width x render.height)");
  run->callback([a, &exit_code] { exit_code = cmd_run(*a); });
  return run;
}

}  // namespace sphray::cli
