#include "sim.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <ostream>
#include <sstream>

#include "pipeline/pipeline.h"
#include "pipeline/setup.h"

namespace sphray {

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t m = v.size() / 2;
  return v.size() % 2 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

double spacing_for_count(const Scene& s, size_t target) {
  double volume = 0;
  for (const auto& b : s.fluid) {
    const Vec3d e = b.box.max - b.box.min;
    volume += e.x * e.y * e.z;
  }
  return std::cbrt(volume / double(std::max<size_t>(target, 1)));
}

namespace {

// Device time by launch name, mean per step over `steps` further steps (timed
// apart from the stage medians: the events around each launch cost a little).
std::vector<KernelTime> kernel_times_per_step(Solver& solver, int steps) {
  take_kernel_times();
  set_kernel_timing(true);
  for (int k = 0; k < steps; ++k) solver.step(1e30);
  set_kernel_timing(false);
  std::vector<KernelTime> times = take_kernel_times();
  for (KernelTime& t : times) t.ms /= steps;
  return times;
}

}  // namespace

std::vector<BenchSimRow> bench_sim(const std::string& scene_json, const std::string& scene_name, Backend b,
                                   const BenchSimOptions& opt, std::ostream& log) {
  std::vector<BenchSimRow> rows;
  const std::vector<std::string> solvers = opt.solvers.empty() ? std::vector<std::string>{""} : opt.solvers;
  for (const std::string& name : solvers) {
    for (size_t target : opt.sizes) {
      std::vector<std::string> overrides = opt.overrides;
      if (!name.empty()) overrides.push_back("sph.solver=" + name);
      const Scene base = parse_scene(scene_json, scene_name, overrides);
      std::ostringstream set;
      set.precision(9);
      set << "sph.spacing=" << spacing_for_count(base, target);
      overrides.push_back(set.str());
      const ResolvedScene s = resolve_scene(parse_scene(scene_json, scene_name, overrides));
      for (bool presence : {false, true}) {
        auto solver = make_solver(s, b, {presence ? PresenceMode::EveryStep : PresenceMode::Off});
        BenchSimRow row;
        row.particles = solver->num_fluid();
        row.boundary = s.size.boundary;
        row.solver = solver_name(solver->kind());
        row.presence = presence;
        log << "  " << row.solver << ", " << row.particles << " particles, presence " << (presence ? "on " : "off")
            << ": to t = " << opt.from << " s, " << opt.warmup << " warm-up + " << opt.steps << " steps\n";
        log.flush();
        advance_to(*solver, opt.from, false);
        for (int k = 0; k < opt.warmup; ++k) solver->step(1e30);
        std::vector<double> g, p, in, tot, wall, dt;
        for (int k = 0; k < opt.steps; ++k) {
          const auto start = std::chrono::steady_clock::now();
          solver->step(1e30);  // returns once the step's work is done (the stage clock waits for it)
          wall.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
          const StageTimes& t = solver->last_stage_times();
          g.push_back(t.grid); p.push_back(t.pairs); in.push_back(t.integrate);
          tot.push_back(t.total());
          dt.push_back(solver->last_limits().dt);
        }
        row.solve = solver->last_solve();
        row.median_ms = {median(g), median(p), median(in)};
        row.median_total_ms = median(tot);
        row.median_wall_ms = median(wall);
        row.median_dt_s = median(dt);
        if (opt.kernels) row.kernels = kernel_times_per_step(*solver, opt.steps);
        rows.push_back(row);
      }
    }
  }
  return rows;
}

nlohmann::json bench_json(const std::string& name, Backend b, const std::string& statistic,
                          const std::vector<std::string>& overrides) {
  nlohmann::json j;
  j["benchmark"] = name;
  j["backend"] = backend_name(b);
  j["device"] = b == Backend::Cuda ? cuda_device_name() : std::string("cpu");
  j["statistic"] = statistic;
  j["overrides"] = overrides;
  return j;
}

nlohmann::json to_json(const std::vector<BenchSimRow>& rows, Backend b, const BenchSimOptions& opt) {
  nlohmann::json j = bench_json("sim", b, "median ms per step", opt.overrides);
  j["warmup_steps"] = opt.warmup;
  j["measured_steps"] = opt.steps;
  j["from_s"] = opt.from;
  j["solvers"] = opt.solvers;
  for (const auto& r : rows)
    j["rows"].push_back({{"solver", r.solver}, {"particles", r.particles}, {"boundary_particles", r.boundary},
                         {"presence", r.presence}, {"iterations", r.solve.iterations},
                         {"divergence_iterations", r.solve.divergence_iterations},
                         {"density_error_mean", r.solve.density_error_mean},
                         {"grid_ms", r.median_ms.grid}, {"pairs_ms", r.median_ms.pairs},
                         {"integrate_ms", r.median_ms.integrate},
                         {"total_ms", r.median_total_ms}, {"wall_ms", r.median_wall_ms}, {"dt_s", r.median_dt_s},
                         {"steps_per_simulated_s", r.median_dt_s > 0 ? 1.0 / r.median_dt_s : 0.0},
                         {"realtime_factor", r.realtime_factor()}});
  for (size_t k = 0; k < rows.size(); ++k)
    for (const KernelTime& kt : rows[k].kernels)
      j["rows"][k]["kernels_ms_per_step"][kt.name] = {{"ms", kt.ms}, {"launches", kt.launches}};
  return j;
}

void print_table(const std::vector<BenchSimRow>& rows, std::ostream& out) {
  out << std::setw(7) << "solver" << std::setw(10) << "particles" << std::setw(10) << "presence" << std::setw(10) << "grid" << std::setw(10)
      << "pairs" << std::setw(11) << "integrate" << std::setw(10) << "total" << std::setw(9) << "wall"
      << std::setw(10) << "dt [ms]" << std::setw(9) << "x real" << "   (median ms per step)\n";
  out << std::fixed << std::setprecision(3);
  for (const auto& r : rows)
    out << std::setw(7) << r.solver << std::setw(10) << r.particles << std::setw(10) << (r.presence ? "on" : "off")
        << std::setw(10)
        << r.median_ms.grid << std::setw(10) << r.median_ms.pairs << std::setw(11) << r.median_ms.integrate
        << std::setw(10) << r.median_total_ms << std::setw(9) << r.median_wall_ms << std::setw(10)
        << 1e3 * r.median_dt_s << std::setw(9) << r.realtime_factor() << "\n";
  for (size_t k = 0; k + 1 < rows.size(); k += 2)
    if (!rows[k].presence && rows[k + 1].presence && rows[k].median_ms.pairs > 0)
      out << "  presence adds " << std::setprecision(1)
          << 100.0 * (rows[k + 1].median_ms.pairs / rows[k].median_ms.pairs - 1.0) << "% to the pair stage at "
          << rows[k].particles << " particles\n";
  for (const auto& r : rows) {
    if (r.kernels.empty()) continue;
    out << "  launches at " << r.particles << " particles, presence " << (r.presence ? "on" : "off")
        << " (ms per step):";
    for (const KernelTime& kt : r.kernels) out << " " << kt.name << " " << std::setprecision(3) << kt.ms;
    out << "\n";
  }
  for (const auto& r : rows)
    if (r.solve.iterations > 0)
      out << "  " << r.solver << " at " << r.particles << " particles: " << r.solve.iterations
          << " iterations"
          << (r.solve.divergence_iterations ? " (+ " + std::to_string(r.solve.divergence_iterations) + " divergence)" : "")
          << ", density error " << std::setprecision(3) << 100 * r.solve.density_error_mean
          << "% mean, " << 100 * r.solve.density_error_max << "% max (last step)\n";
  out << "  grid: the sort, the cell tables and the pair masks; pairs: the wall pressure and the one neighbour\n"
      << "  loop of forces, density rate and presence (pbf: the constraint iterations; dfsph: the forces, the\n"
      << "  pressure solve and the advection); integrate: the step size and the kick, density and drift (pbf: the\n"
      << "  velocity, XSPH and density pass; dfsph: the density pass and the divergence solve);\n"
      << "  total: their sum; wall: the whole step on the host's clock (with the launches and waits between stages);\n"
      << "  dt: the step the solver chose; x real: simulated seconds per wall second at that step (dt / wall)\n";
  out << std::defaultfloat;
}

}  // namespace sphray
