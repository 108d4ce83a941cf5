#include "field.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <ostream>
#include <sstream>

#include "sim.h"
#include "pipeline/pipeline.h"
#include "io/scene.h"
#include "pipeline/setup.h"

namespace sphray {

namespace {

// A 1 m tank whose field volume is exactly volume^3 voxels at refine = 2
// (4 voxels per cell, cell = 4 dx at smoothing_ratio 2, so a voxel is one
// particle spacing): the grid's margin (walls + half a cell) puts the tank
// at 1.5 cells from its origin, and the volume covers the cells the tank
// overlaps, volume / 4 of them when the tank is volume / 4 - 1 cells wide.
// The liquid is the block [0, fx] x [0, 1] x [0, fz] m.
std::string bench_tank_scene(const std::string& name, const std::string& what, double dx, double fx, double fz) {
  const double tank = 1.0;
  std::ostringstream os;
  os.precision(10);
  os << "{\"name\": \"" << name << "\",\n"
     << " \"description\": \"" << what << "\",\n"
     << " \"tank\": {\"min\": [0, 0, 0], \"max\": [" << tank << ", " << tank << ", " << tank << "]},\n"
     << " \"fluid\": [{\"min\": [0, 0, 0], \"max\": [" << fx << ", " << tank << ", " << fz << "]}],\n"
     << " \"sph\": {\"spacing\": " << dx << "},\n"
     << " \"field\": {\"refine\": 2},\n"
     << " \"run\": {\"end_time\": 10}}\n";
  return os.str();
}

double bench_dx(int volume) { return 1.0 / (double(volume) - 4.0); }

}  // namespace

std::string bench_field_scene(size_t particles, int volume) {
  // Column: full tank width in y, a x a in x and z, holding `particles`.
  const double dx = bench_dx(volume);
  const double a = std::min(0.9, std::sqrt(double(particles) * dx * dx * dx));
  return bench_tank_scene("bench_field_" + std::to_string(particles), "dam-break column for sphray bench field", dx, a,
                          a);
}

std::string bench_pool_scene(size_t particles, int volume) {
  const double dx = bench_dx(volume);
  return bench_tank_scene("bench_pool_" + std::to_string(particles), "still pool for sphray bench render", dx, 1.0,
                          std::min(0.9, double(particles) * dx * dx * dx));
}

int default_bench_volume(size_t particles) { return particles <= 200000 ? 64 : 256; }

void simulate_collapse(const Scene& s, Solver& solver, double collapse, std::ostream& log, const std::string& what) {
  const double a = s.fluid.at(0).box.max.x - s.fluid.at(0).box.min.x;
  const double t_end = collapse * std::sqrt(a / (2.0 * length(s.gravity)));
  log << "  " << solver.num_fluid() << " particles" << (what.empty() ? "" : ", " + what) << ": simulating the collapse to t = " << std::setprecision(3) << t_end
      << " s\n";
  log.flush();
  solver.set_presence(PresenceMode::AtUntil);  // the step that reaches the frame computes presence
  while (solver.time() < t_end - 1e-12) solver.step(t_end);
}

std::vector<BenchFieldRow> bench_field(Backend b, const BenchFieldOptions& opt, std::ostream& log) {
  std::vector<BenchFieldRow> rows;
  for (size_t target : opt.sizes) {
    const int volume = opt.volume > 0 ? opt.volume : default_bench_volume(target);
    const ResolvedScene rs = resolve_scene(parse_scene(bench_field_scene(target, volume), "bench_field", opt.overrides));
    const Scene& s = rs.scene;
    const FieldSetup setup = make_field_setup(rs);
    auto solver = make_solver(rs, b, {});
    simulate_collapse(s, *solver, opt.collapse, log,
                      std::to_string(setup.geom.nx) + "x" + std::to_string(setup.geom.ny) + "x" +
                          std::to_string(setup.geom.nz) + " voxels");
    const ParticleView pv = solver->view();

    // One builder per kind (the kind is fixed when a builder is made).
    std::unique_ptr<FieldBuilder> builders[3];
    std::vector<float> reference;
    struct Variant {
      const char* label;
      FieldKind kind;
      bool presence;
      int group;            // threads per particle (0: the builder's default)
      bool gpu_layout = false;  // the other GPU thread layout: on the CPU it only repeats a row
    };
    // The builders' default thread layouts, and on the GPU the others (1, 8
    // or 32 threads per particle; presence also 4), so that the baseline is
    // the fastest naive on this device and each default is seen against the
    // layouts it did not choose.
    const Variant variants[] = {{"naive", FieldKind::Naive, true, 0},
                                {"naive-thread", FieldKind::Naive, true, 1, true},
                                {"naive-8", FieldKind::Naive, true, 8, true},
                                {"naive-warp", FieldKind::Naive, true, 32, true},
                                {"presence", FieldKind::Presence, true, 0},
                                {"presence-thread", FieldKind::Presence, true, 1, true},
                                {"presence-4", FieldKind::Presence, true, 4, true},
                                {"presence-8", FieldKind::Presence, true, 8, true},
                                {"presence-warp", FieldKind::Presence, true, 32, true},
                                {"presence-full", FieldKind::Presence, false, 0},
                                {"gather", FieldKind::Gather, true, 0},
                                {"gather-thread", FieldKind::Gather, true, 1, true},
                                {"gather-8", FieldKind::Gather, true, 8, true},
                                {"gather-warp", FieldKind::Gather, true, 32, true}};
    for (const Variant& v : variants) {
      if (b == Backend::Cpu && v.gpu_layout) continue;
      if (setup.kernel == FieldKernel::Anisotropic && v.kind == FieldKind::Gather) continue;  // spheres only
      if (setup.kernel == FieldKernel::ZhuBridson && v.kind != FieldKind::Gather) continue;  // built by the gather builder only
      if (setup.kernel != FieldKernel::ZhuBridson && v.kind == FieldKind::Gather && v.group != 0) continue;  // spheres: a thread per voxel
      ParticleView view = pv;
      if (!v.presence) view.presence = nullptr;
      std::unique_ptr<FieldBuilder>& builder = builders[int(v.kind)];
      if (!builder) builder = make_field_builder(b, setup, v.kind);
      for (int k = 0; k < opt.warmup; ++k) builder->build(view, false, v.group);
      std::vector<double> ms;
      for (int k = 0; k < opt.frames; ++k) {
        builder->build(view, false, v.group);
        ms.push_back(builder->last_ms());
      }
      BenchFieldRow row;
      row.particles = pv.n;
      row.nx = setup.geom.nx; row.ny = setup.geom.ny; row.nz = setup.geom.nz;
      row.builder = v.label;
      row.median_ms = median(ms);
      row.min_ms = *std::min_element(ms.begin(), ms.end());
      row.max_ms = *std::max_element(ms.begin(), ms.end());
      row.sim_time = solver->time();
      if (opt.kernels) {  // apart from the medians: the events around each launch cost a little
        take_kernel_times();
        set_kernel_timing(true);
        for (int k = 0; k < opt.frames; ++k) builder->build(view, false, v.group);
        set_kernel_timing(false);
        row.kernels = take_kernel_times();
        for (KernelTime& t : row.kernels) t.ms /= opt.frames;
      }
      builder->build(view, /*count=*/true, v.group);
      row.counts = builder->last_counts();
      const std::vector<float> field = builder->download();
      if (reference.empty()) reference = field;  // the first naive build
      row.error = compare_fields(setup.geom.nx, setup.geom.ny, setup.geom.nz, reference, field, setup.shape.iso);
      log << "    " << std::setw(15) << v.label << " " << std::fixed << std::setprecision(3) << row.median_ms << " ms\n"
          << std::defaultfloat;
      log.flush();
      rows.push_back(row);
    }
  }
  return rows;
}

nlohmann::json to_json(const std::vector<BenchFieldRow>& rows, Backend b, const BenchFieldOptions& opt) {
  nlohmann::json j = bench_json("field", b, "median ms per build", opt.overrides);
  j["warmup_builds"] = opt.warmup;
  j["measured_builds"] = opt.frames;
  j["collapse_T"] = opt.collapse;
  j["rows"] = nlohmann::json::array();
  for (const auto& r : rows)
    j["rows"].push_back({{"particles", r.particles},
                         {"volume", {r.nx, r.ny, r.nz}},
                         {"builder", r.builder},
                         {"median_ms", r.median_ms},
                         {"min_ms", r.min_ms},
                         {"max_ms", r.max_ms},
                         {"sim_time_s", r.sim_time},
                         {"init_writes", r.counts.init_writes},
                         {"pairs", r.counts.pairs},
                         {"voxels_touched", r.counts.touched},
                         {"atomics", r.counts.atomics},
                         {"skipped", r.counts.skipped},
                         {"threads_working", r.counts.working},
                         {"longest_thread", r.counts.longest},
                         {"band_voxels", r.error.band},
                         {"misclassified_band", r.error.misclassified_band},
                         {"misclassified_share", r.error.misclassified_share()},
                         {"misclassified_elsewhere", r.error.misclassified_other},
                         {"surface_distance_mean", r.error.mean_distance},
                         {"surface_distance_max", r.error.max_distance},
                         {"surface_points_unmatched", r.error.unmatched}});
  for (size_t k = 0; k < rows.size(); ++k)
    for (const KernelTime& kt : rows[k].kernels)
      j["rows"][k]["kernels_ms_per_build"][kt.name] = {{"ms", kt.ms}, {"launches", kt.launches}};
  return j;
}

void print_table(const std::vector<BenchFieldRow>& rows, std::ostream& out) {
  out << std::setw(9) << "particles" << std::setw(8) << "volume" << std::setw(15) << "builder" << std::setw(10)
      << "ms" << std::setw(9) << "speedup" << std::setw(12) << "touched" << std::setw(12) << "atomics"
      << std::setw(12) << "skipped" << std::setw(10) << "working" << std::setw(8) << "longest" << std::setw(10)
      << "miscl.%" << std::setw(9) << "holes" << std::setw(9) << "d_mean" << std::setw(8) << "d_max" << "\n";
  for (const auto& r : rows) {
    double naive_ms = 1e300;  // the faster naive variant of this size
    for (const auto& q : rows)
      if (q.particles == r.particles && q.builder.rfind("naive", 0) == 0) naive_ms = std::min(naive_ms, q.median_ms);
    out << std::setw(9) << r.particles << std::setw(8) << (std::to_string(r.nx) + "^3").substr(0, 7) << std::setw(15)
        << r.builder << std::fixed << std::setprecision(3) << std::setw(10) << r.median_ms << std::setprecision(2)
        << std::setw(9);
    if (naive_ms < 1e300 && r.median_ms > 0) out << naive_ms / r.median_ms;
    else out << "-";  // no naive build to compare with (Zhu & Bridson's surface: gather only)
    out << std::setw(12) << r.counts.touched
        << std::setw(12) << r.counts.atomics << std::setw(12) << r.counts.skipped << std::setw(10) << r.counts.working
        << std::setw(8) << r.counts.longest << std::setprecision(3)
        << std::setw(10) << 100.0 * r.error.misclassified_share() << std::setw(9) << r.error.misclassified_other
        << std::setw(9) << r.error.mean_distance << std::setw(8) << r.error.max_distance << std::defaultfloat << "\n";
  }
  for (const auto& r : rows) {
    if (r.kernels.empty()) continue;
    out << "  launches at " << r.particles << " particles, " << r.builder << " (ms per build):";
    for (const KernelTime& kt : r.kernels) out << " " << kt.name << " " << std::fixed << std::setprecision(3) << kt.ms;
    out << std::defaultfloat << "\n";
  }
  out << "  (median ms per build; speedup against the faster naive variant; touched/atomics/skipped from one counted build;\n"
         "   working = threads that evaluated a voxel, longest = most voxels one thread evaluated;\n"
         "   miscl.% = voxels within 2 voxels of the naive surface classified differently; holes = differing\n"
         "   voxels farther away; d_mean/d_max = distance between the iso-surfaces in voxels)\n";
}

}  // namespace sphray
