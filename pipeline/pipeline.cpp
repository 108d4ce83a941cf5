#include "pipeline.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <numeric>
#include <ostream>
#include <sstream>
#include <stdexcept>

#include "setup.h"

namespace sphray {

Backend choose_backend(const std::string& name, std::ostream& log) {
  if (name == "cpu") return Backend::Cpu;
  if (name == "cuda") {
    if (!cuda_available())
      throw std::runtime_error("--backend cuda: no CUDA device is available (or sphray was built without CUDA)");
    return Backend::Cuda;
  }
  if (name != "auto") throw std::runtime_error("--backend '" + name + "': must be auto, cpu or cuda");
  if (cuda_available()) {
    log << "backend: cuda (" << cuda_device_name() << ")\n";
    return Backend::Cuda;
  }
  log << "backend: cpu (no CUDA device found)\n";
  return Backend::Cpu;
}

StageNeeds needs_of(const Scene& s, const std::vector<OutputSink*>& sinks) {
  FrameNeeds ever;
  for (const OutputSink* k : sinks) ever |= k->needs_ever();
  StageNeeds n;
  n.field = s.field.every_frame || ever.field;
  // The presence builder reads presence once per frame: only the step that
  // reaches the frame computes it (sph.presence forces every step, for studies).
  const bool for_field =
      n.field && field_needs_presence_step(s, s.field.builder, s.field.kernel == FieldKernel::Anisotropic);
  if (s.sph.presence) n.presence = PresenceMode::EveryStep;
  else if (for_field || ever.presence) n.presence = PresenceMode::AtUntil;
  return n;
}

std::unique_ptr<Solver> make_solver(const ResolvedScene& r, Backend b, const StageNeeds& needs,
                                    const Frame* resume) {
  check_fits(r, b, needs.field);
  const SolverInput in = make_solver_input(r, needs.presence, resume);
  return b == Backend::Cuda ? make_cuda_solver(in) : make_cpu_solver(in);
}

std::unique_ptr<FieldBuilder> make_field(const ResolvedScene& r, Backend b, const StageNeeds& needs) {
  if (!needs.field) return nullptr;
  return make_field_builder(b, make_field_setup(r), r.scene.field.builder);
}

namespace {

std::string format_seconds(double s) {
  std::ostringstream os;
  os << std::fixed << std::setprecision(s < 10 ? 1 : 0) << s << " s";
  return os.str();
}

// The step statistics a run keeps. Step sizes count the steps the solver
// chose freely: the last step before an output time is shortened to land on
// it (PBF and DFSPH: shortened or stretched), and counted in the mean it made
// the mean read below the min.
struct StepTally {
  StageTimes sum;
  double dt_sum = 0;
  double iterations_sum = 0, divergence_iterations_sum = 0, density_error_sum = 0;
  uint64_t free_steps = 0;
  double last_free_dt = 0;  // the progress line's dt

  void add(const Solver& solver, bool free, RunSummary& r) {
    const StageTimes& st = solver.last_stage_times();
    sum.grid += st.grid; sum.pairs += st.pairs; sum.integrate += st.integrate; sum.skin += st.skin;
    sum.exchange += st.exchange;
    const StepLimits& l = solver.last_limits();
    if (free) {
      dt_sum += l.dt;
      last_free_dt = l.dt;
      ++free_steps;
      r.min_dt = std::min(r.min_dt, double(l.dt));
    }
    if (l.bound < kStepBounds) ++r.bound_steps[l.bound];
    if (l.max_speed > r.max_speed) {  // the limits are the state's the step started from
      r.max_speed = l.max_speed;
      r.max_speed_time = solver.time() - l.dt;
      r.max_speed_id = l.fastest_id;
      r.max_speed_at = l.fastest_at;
    }
    r.particle_steps += solver.num_fluid();
    const SolveStats solve = solver.last_solve();
    iterations_sum += solve.iterations;
    divergence_iterations_sum += solve.divergence_iterations;
    r.divergence_iterations_max = std::max(r.divergence_iterations_max, solve.divergence_iterations);
    density_error_sum += solve.density_error_mean;
    r.iterations_max = std::max(r.iterations_max, solve.iterations);
    r.density_error_max = std::max(r.density_error_max, solve.density_error_max);
    r.unconverged_steps += solve.converged ? 0 : 1;
  }
};

// The summary's totals and means, once the run has ended.
// A resumed run counts from where it started (t0, steps0).
void finish_summary(RunSummary& r, const Solver& solver, const StepTally& tally, const FieldBuilder* field,
                    double field_ms, double t0, uint64_t steps0) {
  r.steps = solver.steps() - steps0;
  r.solver = solver_name(solver.kind());
  r.sim_time = solver.time() - t0;
  r.fluid_end = solver.num_fluid();
  r.removed = solver.num_removed();
  r.clamped = solver.num_clamped();
  if (r.steps) {
    const double k = 1.0 / double(r.steps);
    r.mean_stage_ms = {tally.sum.grid * k, tally.sum.pairs * k, tally.sum.integrate * k, tally.sum.skin * k,
                       tally.sum.exchange * k};
    r.iterations_mean = tally.iterations_sum * k;
    r.divergence_iterations_mean = tally.divergence_iterations_sum * k;
    r.density_error_mean = tally.density_error_sum * k;
  }
  // No free step (every step shortened, an output interval below dt): the
  // mean and min of all steps.
  r.mean_dt = tally.free_steps ? tally.dt_sum / double(tally.free_steps)
                               : (r.steps ? r.sim_time / double(r.steps) : 0.0);
  if (!tally.free_steps) r.min_dt = r.mean_dt;
  if (field) {
    r.field_builder = field_kind_name(field->kind());
    r.field_kernel = field_kernel_name(field->setup().kernel);
    r.field_ms_mean = r.field_builds ? field_ms / double(r.field_builds) : 0.0;
    const VolumeGeom& g = field->setup().geom;
    r.field_dims[0] = g.nx; r.field_dims[1] = g.ny; r.field_dims[2] = g.nz;
  }
}

// What the sinks need at a frame, together.
FrameNeeds sinks_need(const std::vector<OutputSink*>& sinks, int frame) {
  FrameNeeds all;
  for (const OutputSink* k : sinks) all |= k->needs(frame);
  return all;
}

}  // namespace

double advance_frame(Solver& solver, int substeps, bool presence, double until) {
  double ms = 0;
  for (int k = 0; k < substeps && solver.time() < until; ++k) {
    solver.set_presence(presence && k == substeps - 1 ? PresenceMode::EveryStep : PresenceMode::Off);
    solver.step(until);
    ms += solver.last_stage_times().total();
  }
  return ms;
}

double playback_target(double sim_time, double last_frame_wall_s, double max_sim_per_frame, double end) {
  return std::min(end, sim_time + std::clamp(last_frame_wall_s, 0.0, max_sim_per_frame));
}

FrameAdvance advance_to(Solver& solver, double until, bool presence, double budget_s) {
  using clock = std::chrono::steady_clock;
  FrameAdvance a;
  const auto t0 = clock::now();
  double elapsed = 0;
  while (solver.time() < until - 1e-12) {
    // The last step: the one that may reach `until` (PresenceMode::AtUntil
    // knows it), or the one after which the budget is spent (on the mean
    // step so far), which then computes presence itself.
    const bool budget_ends = a.steps > 0 && elapsed + elapsed / a.steps > budget_s;
    solver.set_presence(!presence ? PresenceMode::Off : budget_ends ? PresenceMode::EveryStep : PresenceMode::AtUntil);
    solver.step(until);  // returns once the step's work is done
    a.ms += solver.last_stage_times().total();
    ++a.steps;
    elapsed = std::chrono::duration<double>(clock::now() - t0).count();
    if (budget_ends) break;
  }
  a.reached = solver.time() >= until - 1e-12;
  return a;
}

RunSummary run_scene(const Scene& s, Solver& solver, const RunOptions& opt, std::ostream& log) {
  using clock = std::chrono::steady_clock;
  RunSummary r;
  r.backend = solver.backend();
  r.fluid_start = solver.num_fluid();
  const double end = s.run.end_time, every = s.run.output_interval;
  const auto t0 = clock::now();
  auto last_print = t0;
  // A resumed run starts at the output frame of its time; its summary counts
  // the steps and time it simulated.
  int frame = int(std::lround(solver.time() / every));
  const double t0_sim = solver.time();
  const uint64_t steps0 = solver.steps();
  double field_ms = 0;
  // What frame k needs: the field at every frame for a scene whose "field"
  // section asks for it (field.every_frame), else where a sink needs it;
  // presence toward it (when the solver computes it only where needed) where
  // the presence builder builds the field, or a sink needs it.
  auto needs_at = [&](int k) {
    FrameNeeds n = sinks_need(opt.sinks, k);
    n.field = opt.field && (s.field.every_frame || n.field);
    n.presence = n.presence || (n.field && opt.field->kind() == FieldKind::Presence);
    return n;
  };
  const bool presence_by_frame = solver.presence_mode() == PresenceMode::AtUntil;
  auto output = [&] {
    if (opt.gather_frames) solver.gather_frame();
    if (needs_at(frame).field) {
      const ParticleView v = solver.view();
      if (opt.field->kind() == FieldKind::Presence && !v.presence) ++r.field_without_presence;
      opt.field->build(v);
      field_ms += opt.field->last_ms();
      ++r.field_builds;
    }
    for (OutputSink* k : opt.sinks) k->write(solver, opt.field, frame);
  };
  output();
  StepTally tally;

  // Every second, and at the end; also between output times, which may be
  // far apart (render --time T takes one step of output to T).
  auto progress = [&](bool last) {
    const auto now = clock::now();
    if (!opt.progress || (!last && std::chrono::duration<double>(now - last_print).count() < opt.progress_seconds)) return;
    last_print = now;
    const double wall = std::chrono::duration<double>(now - t0).count();
    const double done = solver.time() - t0_sim;
    const double eta = done > 0 ? wall * (end - solver.time()) / done : 0.0;
    log << "  t = " << std::fixed << std::setprecision(4) << solver.time() << " / " << end << " s  step "
        << solver.steps() << "  dt " << std::scientific << std::setprecision(2)
        << (tally.last_free_dt > 0 ? tally.last_free_dt : double(solver.last_limits().dt))
        << " s  " << (wall > 0 ? r.particle_steps / wall : 0.0) << " particle-steps/s  " << std::defaultfloat
        << std::setprecision(3) << "x" << (wall > 0 ? done / wall : 0.0) << " real time  ETA "
        << format_seconds(eta) << "\n";
    log.flush();
  };

  while (solver.time() < end - 1e-12) {
    const double next_output = std::min(end, (frame + 1) * every);
    if (presence_by_frame)
      solver.set_presence(needs_at(frame + 1).presence ? PresenceMode::AtUntil : PresenceMode::Off);
    while (solver.time() < next_output - 1e-12) {
      solver.step(next_output);
      const bool free = solver.time() < next_output - 1e-12;  // not the step landed on the output time
      tally.add(solver, free, r);
      if (free) progress(false);  // the last step's line comes after its output
    }
    ++frame;
    output();
    progress(solver.time() >= end - 1e-12);
  }
  r.wall_seconds = std::chrono::duration<double>(clock::now() - t0).count();
  finish_summary(r, solver, tally, opt.field, field_ms, t0_sim, steps0);
  return r;
}

const char* step_bound_name(const std::string& solver, int bound) {
  switch (bound) {
    case kBoundCfl: return solver == "wcsph" ? "the CFL (sound and flow speed, sph.cfl)" : "the flow CFL (sph.cfl)";
    case kBoundSolver:
      return solver == "wcsph" ? "the force limit"
             : solver == "pbf" ? "the density error and depth limits (pbf.step_error, pbf.step_error_flow, pbf.depth_error)"
                               : "the explicit viscosity's limit (dfsph.viscosity)";
    case kBoundViscous: return "the viscous limit (sph.viscosity_alpha)";
    default: return "run.max_dt";
  }
}

const char* step_bound_key(int bound) {
  static constexpr const char* kKeys[kStepBounds] = {"cfl", "solver", "viscous", "max_dt"};
  return kKeys[bound];
}

namespace {

// "  step size      held by A in 76% of the steps, B in 24%": the limits that
// held the steps (a step landed on an output time counts the limit of the
// step it was shortened or stretched from), the most frequent first.
void print_step_bounds(const RunSummary& r, std::ostream& log) {
  uint64_t total = 0;
  for (uint64_t c : r.bound_steps) total += c;
  if (total == 0) return;
  int order[kStepBounds];
  std::iota(order, order + kStepBounds, 0);
  std::stable_sort(order, order + kStepBounds, [&](int a, int b) { return r.bound_steps[a] > r.bound_steps[b]; });
  log << "  step size      held by ";
  for (int k = 0; k < kStepBounds && r.bound_steps[order[k]] > 0; ++k)
    log << (k ? ", " : "") << step_bound_name(r.solver, order[k]) << " in " << std::setprecision(3)
        << 100.0 * double(r.bound_steps[order[k]]) / double(total)
        << (k ? "%" : "% of the steps");
  log << std::setprecision(4) << "\n";
}

}  // namespace

void print_summary(const RunSummary& r, std::ostream& log) {
  log << std::defaultfloat << std::setprecision(4);
  log << "summary (" << backend_name(r.backend) << ", " << r.solver << "):\n"
      << "  simulated      " << r.sim_time << " s in " << r.steps << " steps (dt mean " << r.mean_dt << " s, min "
      << r.min_dt << " s, of the steps not landed on an output time)\n"
      << "  wall time      " << r.wall_seconds << " s ("
      << (r.wall_seconds > 0 ? double(r.particle_steps) / r.wall_seconds : 0.0) << " particle-steps/s, x"
      << r.realtime_factor() << " real time: simulated seconds per wall second)\n"
      << "  particles      " << r.fluid_start << " fluid at start, " << r.fluid_end << " at end; "
      << r.removed << " left through the open top and were removed\n"
      << "  wall clamps    " << r.clamped << " particle-steps put back on a wall face";
  const double clamp_share = r.particle_steps ? double(r.clamped) / double(r.particle_steps) : 0.0;
  if (r.clamped) log << " (" << 100 * clamp_share << "% of " << r.particle_steps << ")";
  log << "\n";
  if (clamp_share > kWallClampShareBound)
    log << "  warning        the wall guard, not the walls' pressure, held the liquid on more than "
        << 100 * kWallClampShareBound << "% of particle-steps: wall layers thinner than the kernel support "
        << "(sph.boundary_layers below \"auto\"), or steps too large for the flow (lower sph.cfl)\n";
  if (r.iterations_max > 0) {
    const bool dfsph = r.divergence_iterations_max > 0;
    log << (dfsph ? "  pressure solve " : "  constraint     ") << r.iterations_mean << " iterations per step (max "
        << r.iterations_max << ")";
    if (dfsph)
      log << ", divergence solve " << r.divergence_iterations_mean << " (max " << r.divergence_iterations_max << ")";
    log << ", density error " << 100 * r.density_error_mean << "% mean, " << 100 * r.density_error_max
        << "% largest";
    if (r.unconverged_steps)
      log << ", " << r.unconverged_steps << (dfsph ? " steps at an iteration limit above the tolerance"
                                                  : " steps above pbf.tolerance");
    log << "\n";
  }
  log << "  max speed      " << r.max_speed << " m/s";
  if (r.max_speed > 0) {
    log << " at t = " << r.max_speed_time << " s";
    if (r.max_speed_id != kNoBadParticle)
      log << ", particle " << r.max_speed_id << " (initial index) at (" << r.max_speed_at.x << ", "
          << r.max_speed_at.y << ", " << r.max_speed_at.z << ") m";
  }
  log << "\n";
  print_step_bounds(r, log);
  log << "  ms per step    grid (with the pair masks) " << r.mean_stage_ms.grid
      << ", pairs (forces, density rate, presence where needed) " << r.mean_stage_ms.pairs << ", integrate "
      << r.mean_stage_ms.integrate;
  if (r.mean_stage_ms.skin > 0) log << ", obstacle skins " << r.mean_stage_ms.skin;
  if (r.mean_stage_ms.exchange > 0) log << ", exchange with the other ranks " << r.mean_stage_ms.exchange;
  log << "\n";
  if (r.field_builds)
    log << "  field          " << r.field_builder << " builder, " << r.field_kernel
        << (r.field_kernel == field_kernel_name(FieldKernel::ZhuBridson) ? " surface, " : " kernels, ") << r.field_dims[0]
        << "x" << r.field_dims[1] << "x" << r.field_dims[2] << " voxels, " << r.field_builds << " builds, " << r.field_ms_mean << " ms per build"
        << (r.field_without_presence ? " (" + std::to_string(r.field_without_presence) +
                                           " without presence, e.g. at t = 0: full extents)"
                                     : std::string())
        << "\n";
}

}  // namespace sphray
