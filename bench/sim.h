// `sphray bench sim`: milliseconds per SPH step, split by stage, for dam breaks
// of given particle counts, with and without particle presence. Stage times
// come from device events (CUDA) or the steady clock (CPU), after warm-up
// steps, as medians over the measured steps; with them the wall time of each
// whole step on the host's clock.
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/kernel_times.h"
#include "io/scene.h"
#include "sph/solver.h"

namespace sphray {

struct BenchSimOptions {
  std::vector<size_t> sizes;  // target fluid particle counts
  int warmup = 20;
  int steps = 100;
  std::vector<std::string> overrides;  // --set key.path=value, applied to every size
  std::vector<std::string> solvers;    // sph.solver of each series in turn; empty: the scene's
  bool kernels = false;  // also time each named launch (a further `steps` steps, kernel_times.h)
  // Simulated seconds advanced (untimed) before the warm-up: the flow's step
  // sizes, not those of the liquid at rest (a flow-CFL solver steps at
  // run.max_dt until the liquid moves).
  double from = 0;
};

struct BenchSimRow {
  size_t particles = 0, boundary = 0;
  std::string solver;  // sph.solver
  bool presence = false;
  SolveStats solve;    // the last measured step's (iterations, density error)
  StageTimes median_ms;
  double median_total_ms = 0;  // the stages' device time
  // The host's clock around each step() call: the stages plus what the
  // device waits for between them (launches, host round trips), i.e. what a
  // run pays per step.
  double median_wall_ms = 0;
  double median_dt_s = 0;  // the step size the solver chose
  // Simulated seconds per wall second at these steps: median dt over the
  // median wall time of a step (the standing column's steps; a flowing
  // liquid takes smaller ones).
  double realtime_factor() const { return median_wall_ms > 0 ? median_dt_s / (1e-3 * median_wall_ms) : 0.0; }
  std::vector<KernelTime> kernels;  // with BenchSimOptions::kernels: ms per step by launch name
};

// Spacing that gives about `target` fluid particles in the scene's fluid blocks.
double spacing_for_count(const Scene& s, size_t target);

// `scene_json` is the scene's text, `scene_name` names it in messages.
std::vector<BenchSimRow> bench_sim(const std::string& scene_json, const std::string& scene_name, Backend b,
                                   const BenchSimOptions& opt, std::ostream& log);
nlohmann::json to_json(const std::vector<BenchSimRow>& rows, Backend b, const BenchSimOptions& opt);
void print_table(const std::vector<BenchSimRow>& rows, std::ostream& out);

double median(std::vector<double> v);

// What every benchmark's JSON starts with: its name, the backend and device,
// the statistic its numbers are, and the scene overrides it ran with.
nlohmann::json bench_json(const std::string& name, Backend b, const std::string& statistic,
                          const std::vector<std::string>& overrides);

}  // namespace sphray
