// The pipeline: makes only the stages a scene and its outputs need, and runs
// them: SPH steps to each output time, the density field where an output
// needs it, the outputs (sinks), progress lines and the run's summary.
#pragma once

#include <functional>
#include <iosfwd>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "field/field.h"
#include "io/scene.h"
#include "setup.h"
#include "sph/solver.h"

namespace sphray {

// "auto" picks CUDA when a device is present, else CPU; says which on log.
Backend choose_backend(const std::string& name, std::ostream& log);

// What the scene's later stages need from the solver.
struct StageNeeds {
  PresenceMode presence = PresenceMode::Off;
  bool field = false;  // build the density field at output frames
};

// What an output needs at an output frame.
struct FrameNeeds {
  bool field = false;     // the density field, built from the frame's particles
  bool presence = false;  // presence, computed by the step that reaches the frame
  FrameNeeds& operator|=(const FrameNeeds& o) {
    field = field || o.field;
    presence = presence || o.presence;
    return *this;
  }
};

// An output of a run (PNG frames, the HDF5 export, the metrics CSV, a test's
// probe), written at every output frame: t = 0, every output interval and the
// end. It declares what it needs; the pipeline makes only the stages some
// sink (or the scene) needs, and builds the field and computes presence only
// for the frames where one of them needs it.
class OutputSink {
 public:
  virtual ~OutputSink() = default;
  virtual FrameNeeds needs(int frame) const = 0;
  // What it needs at some frame: which stages the run must have.
  virtual FrameNeeds needs_ever() const = 0;
  // `field`: built for this frame when some sink needs it, else null or stale.
  virtual void write(const Solver& solver, const FieldBuilder* field, int frame) = 0;
};

// A sink written as a function, needing `needs` at the frames where `at`
// says so (every frame when null).
class FunctionSink final : public OutputSink {
 public:
  using Write = std::function<void(const Solver&, const FieldBuilder*, int frame)>;
  explicit FunctionSink(Write write, FrameNeeds needs = {}, std::function<bool(int frame)> at = nullptr)
      : write_(std::move(write)), needs_(needs), at_(std::move(at)) {}
  FrameNeeds needs(int frame) const override { return !at_ || at_(frame) ? needs_ : FrameNeeds{}; }
  FrameNeeds needs_ever() const override { return needs_; }
  void write(const Solver& s, const FieldBuilder* f, int frame) override {
    if (!at_ || at_(frame)) write_(s, f, frame);
  }

 private:
  Write write_;
  FrameNeeds needs_;
  std::function<bool(int)> at_;
};

// The stages a scene and its sinks need: the field when the scene has a
// "field" section or a sink needs it; presence on every step (sph.presence),
// on the steps that reach the frames where the presence builder or a sink
// needs it, or never.
StageNeeds needs_of(const Scene& s, const std::vector<OutputSink*>& sinks = {});

std::unique_ptr<Solver> make_solver(const ResolvedScene& r, Backend b, const StageNeeds& needs,
                                    const Frame* resume = nullptr);
// The scene's field builder, or null when no stage needs a field.
std::unique_ptr<FieldBuilder> make_field(const ResolvedScene& r, Backend b, const StageNeeds& needs);

struct RunOptions {
  bool progress = true;
  double progress_seconds = 1.0;  // between progress lines (and at the end)
  // Built before the sinks are written at the frames where the scene (a
  // "field" section: every frame) or a sink needs it.
  FieldBuilder* field = nullptr;
  std::vector<OutputSink*> sinks;
  // Solver::gather_frame at every output frame: a decomposed run's ranks
  // gather their particles on rank 0 for its sinks (every rank must agree;
  // off where no rank writes outputs).
  bool gather_frames = true;
};

// The share of particle-steps the wall guard may put back on a wall face
// before the summary warns (and the stress tests fail): the walls should hold
// the liquid by their pressure, the guard is a safety net.
constexpr double kWallClampShareBound = 0.005;

struct RunSummary {
  Backend backend{};
  std::string solver;  // sph.solver
  size_t fluid_start = 0, fluid_end = 0, removed = 0, boundary = 0;
  uint64_t clamped = 0, steps = 0;
  uint64_t particle_steps = 0;  // fluid particles summed over the steps
  double sim_time = 0, wall_seconds = 0;
  // Simulated seconds per wall second (1: the run keeps pace with real time).
  double realtime_factor() const { return wall_seconds > 0 ? sim_time / wall_seconds : 0.0; }
  double mean_dt = 0, min_dt = 1e300;
  // The steps that each limit held (StepBound, sph/integrate.h; a step
  // landed on an output time: the limit of the step it was shortened or
  // stretched from).
  uint64_t bound_steps[kStepBounds] = {};
  StageTimes mean_stage_ms;
  double max_speed = 0;
  // Where max_speed was reached: the time the step started from, the
  // particle's id (initial index) and position; the id is kNoBadParticle where
  // the solver does not know it (a run over several ranks).
  double max_speed_time = 0;
  uint32_t max_speed_id = kNoBadParticle;
  Vec3f max_speed_at = {0.0f, 0.0f, 0.0f};
  // The constraint or pressure solve of each step (Solver::last_solve; PBF,
  // DFSPH): iterations mean and max (DFSPH: also of the divergence solve),
  // the density error of SolveStats (mean over the steps of each step's mean, and the
  // largest of any particle), steps that missed a tolerance within the limits.
  double iterations_mean = 0, density_error_mean = 0, density_error_max = 0;
  int iterations_max = 0;
  double divergence_iterations_mean = 0;
  int divergence_iterations_max = 0;
  uint64_t unconverged_steps = 0;
  uint64_t field_builds = 0, field_without_presence = 0;  // presence builds that fell back to full extents
  double field_ms_mean = 0;
  std::string field_builder;
  std::string field_kernel;  // isotropic (spheres), anisotropic (ellipsoids) or zhu_bridson (field_kernel_name)
  int field_dims[3] = {0, 0, 0};
};

// One displayed frame of simulation: `substeps` steps (never past `until`),
// presence computed on the last one only when asked for (the field builder
// reads it once per frame). Returns the steps' device milliseconds.
double advance_frame(Solver& solver, int substeps, bool presence, double until);

// Real-time playback: a displayed frame advances the simulation by the wall
// time of the previous frame, at most `max_sim_per_frame` seconds, and never
// past `end`.
double playback_target(double sim_time, double last_frame_wall_s, double max_sim_per_frame, double end);

// What advance_to did.
struct FrameAdvance {
  double ms = 0;  // the steps' device milliseconds
  int steps = 0;
  bool reached = true;  // false: the wall-time budget ended the frame first
};
// Steps toward `until` (step() never passes it) until it is reached or the
// steps have taken `budget_s` of wall time: a machine too slow for real time
// then plays slower at a steady frame rate instead of taking ever more steps
// per frame. Presence, when asked for, on the last step.
FrameAdvance advance_to(Solver& solver, double until, bool presence,
                        double budget_s = std::numeric_limits<double>::infinity());

RunSummary run_scene(const Scene& s, Solver& solver, const RunOptions& opt, std::ostream& log);
void print_summary(const RunSummary& r, std::ostream& log);

// A StepBound (sph/integrate.h) as the summary names it for `solver`
// (sph.solver's name), and its key in the summary JSON's "step_bounds".
const char* step_bound_name(const std::string& solver, int bound);
const char* step_bound_key(int bound);

}  // namespace sphray
