// The pipeline: builds only the stages a scene needs and drives them. Today
// the stages are the SPH solver and per-output sinks (progress, metrics CSV);
// the field builder, renderer and HDF5 writer plug in as further sinks.
#pragma once

#include <functional>
#include <iosfwd>
#include <memory>
#include <string>

#include "field.h"
#include "scene.h"
#include "solver.h"

namespace sphray {

// "auto" picks CUDA when a device is present, else CPU; says which on log.
Backend choose_backend(const std::string& name, std::ostream& log);

// What the scene's later stages need from the solver.
struct StageNeeds {
  PresenceMode presence = PresenceMode::Off;
  bool field = false;  // build the density field at every output frame
};
// The sinks may ask for more than the scene does: a field (an export of the
// field) or presence (an export of presence).
StageNeeds needs_of(const Scene& s, bool field_sink = false, bool presence_sink = false);

std::unique_ptr<Solver> make_solver(const Scene& s, Backend b, const StageNeeds& needs);
// The scene's field builder, or null when no stage needs a field.
std::unique_ptr<FieldBuilder> make_field(const Scene& s, Backend b, const StageNeeds& needs);

struct RunOptions {
  bool progress = true;
  double progress_seconds = 1.0;  // between progress lines (and at the end)
  // Built at every output frame, before on_output (which may read it).
  FieldBuilder* field = nullptr;
  FieldKind field_kind = FieldKind::Presence;
  // Which output frames need the field (null: all of them).
  std::function<bool(int frame)> field_at;
  // Which output frames need presence (null: whatever mode the solver has).
  // Set, the steps toward frame k compute presence (on the one that reaches
  // it, PresenceMode::AtUntil) only when presence_at(k); otherwise none.
  std::function<bool(int frame)> presence_at;
  // Called at t = 0 and after every output interval, and at the end.
  std::function<void(const Solver&, int frame)> on_output;
};

// The share of particle-steps the wall guard may put back on a wall face
// before the summary warns (and the stress tests fail): the walls should hold
// the liquid by their pressure, the guard is a safety net.
constexpr double kWallClampShareBound = 0.005;

struct RunSummary {
  Backend backend{};
  size_t fluid_start = 0, fluid_end = 0, removed = 0, boundary = 0;
  uint64_t clamped = 0, steps = 0;
  uint64_t particle_steps = 0;  // fluid particles summed over the steps
  double sim_time = 0, wall_seconds = 0;
  double mean_dt = 0, min_dt = 1e300;
  StageTimes mean_stage_ms;
  double max_speed = 0;
  uint64_t field_builds = 0, field_without_presence = 0;  // presence builds that fell back to full extents
  double field_ms_mean = 0;
  std::string field_builder;
  int field_dims[3] = {0, 0, 0};
};

// One displayed frame of simulation: `substeps` steps (never past `until`),
// presence computed on the last one only when asked for (the field builder
// reads it once per frame). Returns the steps' device milliseconds.
double advance_frame(Solver& solver, int substeps, bool presence, double until);

RunSummary run_scene(const Scene& s, Solver& solver, const RunOptions& opt, std::ostream& log);
void print_summary(const RunSummary& r, std::ostream& log);

}  // namespace sphray
